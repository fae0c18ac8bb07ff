"""Vectorized tokenizer for line-based text mesh formats (OBJ, OFF, ASCII PLY/STL).

:class:`TextTokens` splits a byte buffer into lines and whitespace-separated tokens with
numpy only (no Python work per line): a token is a maximal run of non-whitespace bytes,
and lines know their tokens. Plain decimals are parsed exactly by integer arithmetic on
right-aligned digit columns; anything else (exponents, nan, inf) by numpy's C
string-to-number cast. Every parse error names the line (1-based) and the offending token.
"""

from __future__ import annotations

import numpy as np

from decrun.errors import MeshError

_WHITESPACE = np.zeros(256, dtype=bool)
_WHITESPACE[[9, 10, 11, 12, 13, 32]] = True  # \t \n \v \f \r space
_MAX_NUMBER_WIDTH = 64  # no decimal number in a mesh file is longer
_BLOCK = 1 << 15  # tokens parsed at once: their (block, <= 19) digit matrices stay in cache


class TextTokens:
    """Lines and tokens of a text buffer.

    Attributes (L lines, T tokens; positions are byte offsets into ``buffer``):

    - ``buffer`` (N,) uint8, the file with a final ``\\n`` appended
    - ``line_start``, ``line_end`` (L,) int64, a line spans ``[start, end)`` without ``\\n``
    - ``token_start``, ``token_end`` (T,) int64
    - ``line_first_token``, ``line_token_count`` (L,) int64

    ``comment`` (a byte such as ``b"#"``), if given, starts a comment that runs to the end
    of its line; comment bytes are treated as whitespace. ``first_line`` and ``first_byte``
    place the buffer in its file (for a body that follows a header). A control byte other
    than whitespace (NUL, ...) is a :class:`MeshError`: the file is not text.
    """

    def __init__(self, raw: bytes, where: str, comment: bytes | None = None, first_line: int = 1, first_byte: int = 0):
        self.where, self.first_line = where, first_line
        # zero bytes after the final newline let fixed-width gathers run past a token's end
        n = len(raw)
        self._padded = np.zeros(n + 1 + _MAX_NUMBER_WIDTH, dtype=np.uint8)
        self._padded[:n] = np.frombuffer(raw, dtype=np.uint8)
        self._padded[n] = 10
        if raw.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte order mark reads as blanks
            self._padded[:3] = 32
        buffer = self.buffer = self._padded[:n + 1]
        control = np.flatnonzero(buffer < 32)
        control_byte = buffer[control]
        binary = np.flatnonzero(~_WHITESPACE[control_byte])
        if binary.size:
            raise MeshError(f"{where}: not a text file: binary content at byte {int(control[binary[0]]) + first_byte}")
        newline = control[control_byte == 10]
        self.line_start = np.concatenate([[0], newline[:-1] + 1]).astype(np.int64)
        self.line_end = newline.astype(np.int64)
        blank = buffer <= 32  # the text check above leaves only whitespace below 33
        if comment is not None:
            hashes = np.flatnonzero(buffer == comment[0])
            if hashes.size:
                hash_line = np.searchsorted(newline, hashes)
                first = np.ones(hashes.size, dtype=bool)
                first[1:] = hash_line[1:] != hash_line[:-1]
                # +1 at the first comment byte of a line, -1 at that line's newline
                lo, hi = int(hashes[0]), int(newline[hash_line[-1]]) + 1  # only where comments are
                step = np.zeros(hi - lo, dtype=np.int8)
                step[hashes[first] - lo] += 1
                step[newline[hash_line[first]] - lo] -= 1
                blank[lo:hi] |= np.cumsum(step, dtype=np.int8) > 0
        # blank/solid changes alternate: token starts and ends (the buffer ends blank)
        change = np.flatnonzero(blank[1:] != blank[:-1]) + 1
        if not blank[0]:
            change = np.concatenate([[0], change])
        self.token_start = np.ascontiguousarray(change[0::2])
        self.token_end = np.ascontiguousarray(change[1::2])
        self.newline = newline
        # no token starts at a newline, so line i's first token is the first after line i-1's end
        tokens_before_end = np.searchsorted(self.token_start, self.line_end)
        self.line_first_token = np.concatenate([[0], tokens_before_end[:-1]]).astype(np.int64)
        self.line_token_count = tokens_before_end - self.line_first_token

    # ------------------------------------------------------------------ text access

    def token_text(self, token: int) -> str:
        """The text of one token (for messages)."""
        a, b = int(self.token_start[token]), int(self.token_end[token])
        text = self.buffer[a:min(b, a + 40)].tobytes().decode("latin-1")
        return text + ("..." if b - a > 40 else "")

    def line_text(self, line: int) -> str:
        """The text of one 0-based line, shortened (for messages)."""
        a, b = int(self.line_start[line]), int(self.line_end[line])
        text = self.buffer[a:min(b, a + 60)].tobytes().decode("latin-1").strip()
        return text + (" ..." if b - a > 60 else "")

    def line_tokens(self, lines: np.ndarray, skip: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """All tokens of ``lines`` after the first ``skip`` of each line, line by line.

        Returns ``(tokens, offsets)``: token indices (Σ counts,) and (len(lines)+1,) offsets
        so that line ``lines[i]``'s tokens are ``tokens[offsets[i]:offsets[i+1]]``.
        """
        lines = np.asarray(lines, dtype=np.int64)
        counts = np.maximum(self.line_token_count[lines] - skip, 0)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        first = self.line_first_token[lines] + skip
        tokens = np.repeat(first - offsets[:-1], counts) + np.arange(offsets[-1], dtype=np.int64)
        return tokens, offsets

    def characters(self, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Byte ranges ``[starts, ends)`` as a (len, width) uint8 matrix, zero-padded;
        ranges longer than ``_MAX_NUMBER_WIDTH`` are cut there."""
        starts = np.asarray(starts, dtype=np.int64)
        lengths = np.asarray(ends, dtype=np.int64) - starts
        width = int(min(max(lengths.max(initial=1), 1), _MAX_NUMBER_WIDTH))
        position = starts.astype(np.int32 if self._padded.size < 2**31 else np.int64)
        chars = np.empty((starts.size, width), dtype=np.uint8)
        for j in range(width):  # one gather per character column (at most 64), not per token
            chars[:, j] = self._padded[position + j]
        chars[np.arange(width) >= lengths[:, None]] = 0
        return chars

    def gather(self, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Byte ranges ``[starts, ends)`` as a fixed-width ``S`` array (shorter ones zero-padded)."""
        chars = self.characters(starts, ends)
        return chars.view(f"S{chars.shape[1]}").ravel()

    # ------------------------------------------------------------------ numbers

    def line_number(self, line):
        """File line number (1-based) of 0-based buffer line index(es) ``line``."""
        return line + self.first_line

    def line_at(self, position: int) -> int:
        """File line number (1-based) of a byte position."""
        return int(np.searchsorted(self.newline, position)) + self.first_line

    def token_numbers(self, tokens: np.ndarray, dtype, what: str) -> np.ndarray:
        """Parse whole tokens (indices) as numbers, see :meth:`numbers`."""
        tokens = np.asarray(tokens, dtype=np.int64)
        return self.numbers(self.token_start[tokens], self.token_end[tokens], dtype, what)

    def numbers(self, starts: np.ndarray, ends: np.ndarray, dtype, what: str) -> np.ndarray:
        """Parse byte ranges as ``float64`` or ``int64``; ``what`` names them in errors
        (e.g. ``"vertex coordinate"``).

        Plain decimals (``[+-]digits[.digits]``, at most 15 significant digits) are parsed
        by integer arithmetic on the digit columns: mantissa and power of ten are exact, so
        one IEEE division rounds correctly, the same value ``float()`` gives. Everything
        else (exponents, nan, inf, long mantissas) goes through numpy's string cast.
        """
        starts = np.asarray(starts, dtype=np.int64)
        ends = np.asarray(ends, dtype=np.int64)
        if starts.size == 0:
            return np.zeros(0, dtype=dtype)
        lengths = ends - starts
        bad = np.flatnonzero((lengths <= 0) | (lengths > _MAX_NUMBER_WIDTH))
        if bad.size:
            self._number_error(starts, ends, bad[0], what, dtype)
        integer = np.dtype(dtype).kind == "i"
        values = np.zeros(starts.size, dtype=np.int64 if integer else np.float64)
        done = np.zeros(starts.size, dtype=bool)
        pick = np.flatnonzero(lengths <= _FAST_PLACES + 1)  # sign, digits, dot: fast-path candidates
        for lo in range(0, pick.size, _BLOCK):  # blocks keep the digit matrices in cache
            block = pick[lo:lo + _BLOCK]
            values[block], done[block] = _plain_decimals(self._padded, starts[block], ends[block], integer)
        if done.all():
            return values.astype(dtype)
        rest = np.flatnonzero(~done)
        chars = self.characters(starts[rest], ends[rest])
        text = chars.view(f"S{chars.shape[1]}").ravel()
        underscore = np.flatnonzero((chars == ord("_")).any(axis=1))  # Python accepts 1_000
        if underscore.size:
            self._number_error(starts, ends, rest[underscore[0]], what, dtype)
        out = values.astype(dtype)
        try:
            out[rest] = text.astype(dtype)
        except (ValueError, OverflowError):
            # the error path only: find the first token that does not parse
            for i in range(text.size):
                try:
                    text[i:i + 1].astype(dtype)
                except (ValueError, OverflowError):
                    self._number_error(starts, ends, rest[i], what, dtype)
            raise  # pragma: no cover - the loop above always finds the culprit
        return out

    def _number_error(self, starts, ends, i, what, dtype) -> None:
        a, b = int(starts[i]), int(ends[i])
        token = self.buffer[a:min(b, a + 40)].tobytes().decode("latin-1")
        kind = "an integer" if np.dtype(dtype).kind == "i" else "a number"
        shown = repr(token) if b > a else "nothing"
        raise MeshError(f"{self.where}: line {self.line_at(a)}: {what} {shown} is not {kind}")


_FAST_PLACES = 19  # digits and dot of a fast-path token: 10**19 < 2**64, a uint64
_EXACT_DIGITS = 15  # 10**15 < 2**53: the mantissa is an exact float64
_POWERS = 10 ** np.arange(_FAST_PLACES + 1, dtype=np.uint64)
# x87 extended precision (64-bit significand) where numpy has it, else None
_EXTENDED = np.longdouble if np.finfo(np.longdouble).nmant >= 63 else None
if _EXTENDED is not None:  # 10**k, exact for k <= 27 (5**27 < 2**64)
    _EXTENDED_POWERS = np.cumprod(np.concatenate([[_EXTENDED(1)], np.full(_FAST_PLACES, _EXTENDED(10))]))


def _plain_decimals(buffer: np.ndarray, starts: np.ndarray, ends: np.ndarray, integer: bool) -> tuple[np.ndarray, np.ndarray]:
    """Values of tokens ``[+-]digits[.digits]`` (no dot if ``integer``) and the mask of the
    tokens that have this form and were converted exactly (others: value 0, mask False).

    The tokens are right-aligned in a (T, w <= 19) digit matrix; Horner's rule over the
    columns, reading the dot as a 0 digit, gives the uint64 ``raw = left·10**(f+1) + right``
    (f digits after the dot), hence the mantissa ``M = left·10**f + right`` (<= 18 digits)
    and the value M / 10**f:

    - M < 10**15 < 2**53: M and 10**f are exact doubles, one IEEE division rounds correctly;
    - 16..18 digits: M and 10**f are exact in x87 extended precision, the quotient q is
      rounded once to 64 bits; rounding q to double is then correct unless q lies exactly
      on a midpoint between two doubles (the true value may lie on either side): those
      few tokens, and all of them without extended precision, go to the string cast."""
    count = starts.size
    width = int(min(_FAST_PLACES, (ends - starts).max()))
    first = buffer[starts]
    negative = first == 45
    signed = negative | (first == 43)
    index_type = np.int32 if buffer.size < 2**31 else np.int64
    body = (starts + signed).astype(index_type)
    places = ends - body
    index = ends.astype(index_type)[:, None] + np.arange(-width, 0, dtype=index_type)
    outside = index < body[:, None]
    chars = buffer[index]  # index >= -width: wraps into the zero padding at the end
    digit = chars - np.uint8(48)  # bytes below '0' wrap around to >= 10
    digit[outside] = 0
    bad = digit >= 10
    dots = np.zeros(count, dtype=np.int64)
    if not integer:
        is_dot = digit == np.uint8(254)  # "." is 46 = 48 - 2
        bad &= ~is_dot
        digit[is_dot] = 0
        dot_at = np.flatnonzero(is_dot.ravel())
        dots = np.bincount(dot_at // width, minlength=count)
    digits = places - dots
    ok = (places <= width) & (digits > 0) & (digits <= 18) & (dots <= 1)
    ok[np.flatnonzero(bad.ravel()) // width] = False
    digit[~ok] = 0
    raw = np.zeros(count, dtype=np.uint64)
    ten = np.uint64(10)
    for j in range(width):  # Horner over the (at most 19) digit columns
        raw *= ten
        raw += digit[:, j]
    if integer:
        value = raw.astype(np.int64)
    else:
        fraction = np.zeros(count, dtype=np.int64)
        fraction[dot_at // width] = width - 1 - dot_at % width
        scale = _POWERS[fraction]
        mantissa = np.where(dots > 0, raw // (scale * ten) * scale + raw % scale, raw)
        value = mantissa.astype(np.float64) / scale.astype(np.float64)
        long = np.flatnonzero(ok & (digits > _EXACT_DIGITS))
        if long.size and _EXTENDED is None:
            ok[long] = False
        elif long.size:
            q = mantissa[long].astype(_EXTENDED) / _EXTENDED_POWERS[fraction[long]]
            nearest = q.astype(np.float64)
            middle = nearest.astype(_EXTENDED)
            up = np.nextafter(nearest, np.inf).astype(_EXTENDED)
            down = np.nextafter(nearest, -np.inf).astype(_EXTENDED)
            tie = (q == (middle + up) / 2) | (q == (middle + down) / 2)
            value[long] = nearest
            ok[long[tie]] = False
    np.negative(value, out=value, where=negative)
    return value, ok


def is_text(raw: bytes) -> int:
    """-1 if ``raw`` looks like text (no control byte other than whitespace, no DEL),
    else the offset of the first byte that is not text."""
    data = np.frombuffer(raw, dtype=np.uint8)
    whitespace = sum(np.count_nonzero(data == c) for c in (9, 10, 11, 12, 13))  # five byte values
    if np.count_nonzero(data < 32) == whitespace and not np.count_nonzero(data == 127):
        return -1
    control = np.ones(256, dtype=bool)
    control[32:127] = control[128:] = False
    control[_WHITESPACE] = False
    return int(np.flatnonzero(control[data])[0])
