"""Closed sets of option values as ``Enum`` fields (the model: hydra-optuna-sweeper's
``Direction``): a plugin field typed with a :class:`Choice` accepts exactly its members.

OmegaConf checks such a field when the runner builds the plugin
(:func:`decrun.runner.plugins.build`); :meth:`Choice.of` checks it for Python callers
(``CGSolver(preconditioner="none")``), and both name the key and every choice. A member's
name is its value and it *is* that string (``Refine.loop == "loop"``, ``f"{Refine.loop}"``
is ``loop``), so code and messages keep reading plain strings.
"""

from __future__ import annotations

from enum import Enum
from typing import Self

from decrun.errors import ConfigError

__all__ = ["Choice", "choice_error"]


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


def choice_error(key: str, value, choices: type[Choice]) -> ConfigError:
    """``<key>: must be one of a | b | c, got 'x' (e.g. <key>=a)`` — the CLI override that fixes it."""
    names = choices.names()
    return ConfigError(f"{key}: must be one of {' | '.join(names)}, got {str(value)!r} (e.g. {key}={names[0]})")
