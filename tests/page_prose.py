"""The prose of a markdown page, for the guards that scan it for numbers typed by hand
(tests/test_doc_typed_numbers.py: every page; tests/test_fluid_page_numbers.py: the fluid
pages). ``tests/`` is on ``sys.path``: ``from page_prose import prose, numbers_in``.

What is not prose is blanked — replaced by spaces of the same length, newlines kept — so a
position in the prose is the position on the page and its line the page's line. By default
(:data:`NOT_PROSE`): fenced code blocks (``` or ~~~, indented too), inline code (which may
break one line), ``{{ … }}`` placeholders (the numbers made by scripts/doc_numbers.py), images,
link targets and HTML comments; a guard may name its own patterns instead, and more of them
(references such as §5.2 or Fig. 6.9)."""

from __future__ import annotations

import re
from typing import Iterator

FENCE = re.compile(r"^(\s*)(```|~~~).*?^\s*\2", flags=re.M | re.S)
INLINE_CODE = re.compile(r"`[^`\n]*(?:\n[^`\n]+)?`")
PLACEHOLDER = re.compile(r"\{\{[^}]*\}\}")
IMAGE = re.compile(r"!\[[^\]]*\]\([^)]*\)")
LINK_TARGET = re.compile(r"\]\([^)]*\)")
HTML_COMMENT = re.compile(r"<!--.*?-->", flags=re.S)
NOT_PROSE = (FENCE, INLINE_CODE, PLACEHOLDER, IMAGE, LINK_TARGET, HTML_COMMENT)


def blank(match: re.Match) -> str:
    """The matched text as spaces, its newlines kept."""
    return re.sub(r"[^\n]", " ", match.group(0))


def prose(text: str, *more: re.Pattern, not_prose: tuple[re.Pattern, ...] = NOT_PROSE) -> str:
    """``text`` with the patterns ``not_prose`` and then ``more`` blanked, in that order (same
    length, same lines)."""
    for pattern in (*not_prose, *more):
        text = pattern.sub(blank, text)
    return text


def numbers_in(body: str, number: re.Pattern) -> Iterator[tuple[int, re.Match]]:
    """``(line, match)`` for every match of ``number`` in ``body`` (a :func:`prose`), its line
    counted from 1."""
    for match in number.finditer(body):
        yield body.count("\n", 0, match.start()) + 1, match
