"""Typed errors of decrun.

Every error a user can cause by bad input is a :class:`DecrunError`. The CLI prints its
message (no traceback unless asked) and exits non-zero.
"""


class DecrunError(Exception):
    """Base class of every user-facing decrun error.

    ``python_hint`` is the fix for Python callers (``orient='fix'``), appended in brackets to
    the message; the runner replaces it with the CLI override that fixes the same problem
    (:func:`decrun.runner.job.hints.cli_message`), so a command-line user never reads about
    keyword arguments.
    """

    def __init__(self, message: str = "", *, python_hint: str = ""):
        super().__init__(message)
        self.message = message
        self.python_hint = python_hint

    def __str__(self) -> str:
        return f"{self.message} ({self.python_hint})" if self.python_hint else self.message


class MeshError(DecrunError, ValueError):
    """A mesh is unusable; the message names the offending simplices."""


class IndexOutOfRangeError(MeshError):
    """A simplex references a vertex index outside ``[0, n_vertices)``."""


class RepeatedVertexError(MeshError):
    """A simplex lists the same vertex twice."""


class DuplicateSimplexError(MeshError):
    """Two top simplices have the same vertex set."""


class NonFiniteCoordinateError(MeshError):
    """A vertex coordinate is NaN or infinite."""


class DegenerateSimplexError(MeshError):
    """A top simplex has zero (or numerically zero) volume."""


class NonManifoldError(MeshError):
    """A face lies in more than two top simplices, or a vertex star is not a (half-)ball."""


class OrientationError(MeshError):
    """Neighbouring top simplices are oriented inconsistently (§2.3.4)."""


class NonOrientableError(OrientationError):
    """No consistent orientation exists (e.g. a Möbius strip)."""


class UnreferencedVertexError(MeshError):
    """A vertex is used by no top simplex."""


class TopologyError(DecrunError, ValueError):
    """The mesh is valid but has the wrong topology for the requested method."""


class ConfigError(DecrunError, ValueError):
    """A configuration value is invalid; the message names the key."""


class SolverError(DecrunError, RuntimeError):
    """A linear solve failed (singular matrix, no convergence)."""


class CorruptFileError(DecrunError, ValueError):
    """A file decrun reads back (``result.h5``, its journal, ``metrics.json``,
    ``manifest.json``, ``overrides.yaml``) is truncated, altered or not what decrun writes;
    the message names the file and what is wrong with it."""


#: a word (a run of non-blank characters) longer than this is cut in a message
LONG_WORD = 160


def shorten_words(text: str, head: int = 60, tail: int = 16) -> str:
    """``text`` with every word longer than :data:`LONG_WORD` characters — a 120 kB override
    value, a path of thousands of characters — cut to its first ``head`` and last ``tail``
    characters around ``…(<n> characters)…``: an error line stays a line, and still shows
    where the value starts and ends."""
    import re

    def cut(match) -> str:
        word = match.group()
        return f"{word[:head]}…({len(word)} characters)…{word[-tail:]}"

    return re.sub(rf"\S{{{LONG_WORD + 1},}}", cut, text) if len(text) > LONG_WORD else text


def format_point(point, digits: int = 6) -> str:
    """``[x, y, z]`` as a message or a hint quotes it: ``digits`` significant digits, after
    rounding every coordinate at 1e-9 of the point's largest one, so a coordinate that is
    round-off next to the others (``-1.299e-19`` beside ``1.05``) reads ``0`` — what a user
    would type — and no zero carries a sign. Only the text is rounded, never the point the
    run uses."""
    import math

    values = [float(v) for v in point]
    scale = max((abs(v) for v in values if math.isfinite(v)), default=0.0)
    decimals = 9 - math.floor(math.log10(scale)) if scale > 0 else 0
    rounded = [round(v, decimals) + 0.0 if math.isfinite(v) else v for v in values]
    return "[" + ", ".join(f"{v:.{digits}g}" for v in rounded) + "]"
