"""Closed sets of option values as ``Enum`` fields (the model: hydra-optuna-sweeper's
``Direction``): a plugin field typed with a :class:`Choice` accepts exactly its members.

OmegaConf checks such a field when the runner builds the plugin
(:func:`decrun.runner.job.plugins.build`); :meth:`Choice.of` checks it for Python callers
(``CGSolver(preconditioner="none")``), and both name the key and every choice. A member's
name is its value and it *is* that string (``Refine.loop == "loop"``, ``f"{Refine.loop}"``
is ``loop``), so code and messages keep reading plain strings.
"""

from __future__ import annotations

from enum import Enum
from typing import Self

from decrun.errors import ConfigError

__all__ = ["Choice", "choice_error", "closest", "value_hint"]


class Choice(str, Enum):
    """Base of the option enums: members ``name = "name"``."""

    def __str__(self) -> str:
        return str.__str__(self)

    def __format__(self, spec: str) -> str:
        return str.__format__(str(self), spec)

    @classmethod
    def names(cls) -> list[str]:
        """The choices, in declaration order."""
        return [member.value for member in cls]

    @classmethod
    def of(cls, value, key: str) -> Self:
        """``value`` as a member; ConfigError naming ``key`` and the choices otherwise."""
        try:
            return cls(value)
        except ValueError:
            raise choice_error(key, value, cls) from None


def closest(value, names) -> str | None:
    """The one of ``names`` closest in spelling to ``value`` — ``difflib.get_close_matches``
    (cutoff 0.6), the rule the key typos' did-you-mean uses — compared without case
    (``Fix`` → ``fix``); None when none is that close."""
    import difflib

    lowered = {str(name).lower(): str(name) for name in names}
    found = difflib.get_close_matches(str(value).lower(), list(lowered), n=1)
    return lowered[found[0]] if found else None


def value_hint(key: str, value, names) -> str:
    """The override that fixes ``<key>=<value>`` for a key whose values are ``names``:
    ``did you mean <key>=<closest>?`` (:func:`closest`), else ``e.g. <key>=<first name>``
    beside the listed values."""
    names = [str(name) for name in names]
    near = closest(value, names)
    return f"did you mean {key}={near}?" if near is not None else f"e.g. {key}={names[0]}"


def choice_error(key: str, value, choices) -> ConfigError:
    """``<key>: must be one of a | b | c, got 'x' (did you mean <key>=b?)`` — the closest
    choice as the CLI override that fixes it (:func:`value_hint`; ``(e.g. <key>=a)`` when no
    choice is close). ``choices``: a :class:`Choice` enum or the names themselves."""
    names = choices.names() if isinstance(choices, type) and issubclass(choices, Choice) else [str(c) for c in choices]
    return ConfigError(f"{key}: must be one of {' | '.join(names)}, got {str(value)!r} ({value_hint(key, value, names)})")
