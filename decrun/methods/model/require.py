"""What a model requires of its constants: ``require: ["Du > 0", "n >= 1"]``, checked before any
mesh work so that a constant that makes the model ill-posed (a negative diffusivity, a flow-law
exponent below 1, dt ≤ 0) is one line naming the constant, the requirement and where it was
declared, with a command-line override that satisfies it.

A requirement is ``left OP right`` with OP one of ``>``, ``>=``, ``<``, ``<=`` and two
expressions of the model language (:func:`~decrun.methods.model.language.parse_expression`, the
same whitelist) over numbers, the model's constants, ``dt`` and ``pi``, with the functions
``sqrt exp log abs min max``. Nothing is evaluated by Python's ``eval``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from decrun.methods.model.language import (
    Binary,
    Call,
    ModelError,
    Name,
    Negate,
    Node,
    Number,
    names_in,
    parse_expression,
)

__all__ = ["Requirement", "parse_requirement", "check_requirements"]

_COMPARISON = re.compile(r"(>=|<=|>|<|==|!=)")
_ARITHMETIC = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "**": np.power}
_TESTS = {">": lambda a, b: a > b, ">=": lambda a, b: a >= b, "<": lambda a, b: a < b, "<=": lambda a, b: a <= b}
#: numpy's functions, so that exp(1000) is inf (IEEE 754) and not Python's OverflowError: a requirement
#: ``exp(exp(exp(k*10))) > 0`` holds (inf > 0); a nan fails every comparison
_FUNCTIONS: dict[str, Callable[..., Any]] = {"sqrt": np.sqrt, "exp": np.exp, "log": np.log, "abs": np.abs,
                                             "min": min, "max": max}


@dataclass(frozen=True)
class Requirement:
    """One parsed requirement: ``left op right``; ``where`` its config key
    (``app.require[0]``, ``app.parts.glen_law.require[1]``), ``text`` as written."""

    left: Node
    op: str
    right: Node
    where: str
    text: str

    def names(self) -> set[str]:
        return names_in(self.left) | names_in(self.right)


def parse_requirement(text, where: str) -> Requirement:
    """``"Du > 0"`` → :class:`Requirement`; ModelError naming ``where`` for anything else."""
    if not isinstance(text, str):
        raise ModelError(f"{where}: a requirement is a string such as 'Du > 0', got {text!r}")
    pieces = _COMPARISON.split(text)
    if len(pieces) != 3 or pieces[1] not in _TESTS:
        raise ModelError(f"{where}: a requirement is one comparison `left > right` (>, >=, <, <=) of constants, "
                         f"e.g. 'Du > 0' or 'n >= 1'; got {text!r}")
    left, op, right = pieces
    return Requirement(parse_expression(left, where), op, parse_expression(right, where), where, text.strip())


def _value(node: Node, values: dict[str, float], where: str) -> float:
    if isinstance(node, Number):
        return float(node.value)
    if isinstance(node, Name):
        if node.name == "pi":
            return math.pi
        if node.name not in values:
            raise ModelError(f"{where}: {node.name!r} is not a constant of the model; a requirement reads "
                             f"constants, dt and numbers only (constants: {sorted(values)})")
        return float(values[node.name])
    if isinstance(node, Negate):
        return -_value(node.operand, values, where)
    if isinstance(node, Binary) and node.op != "^":
        a, b = _value(node.left, values, where), _value(node.right, values, where)
        with np.errstate(all="ignore"):  # IEEE 754: 1/0 is inf, 0/0 and (-8)**(1/3) are nan
            return float(_ARITHMETIC[node.op](np.float64(a), np.float64(b)))
    if isinstance(node, Call) and node.function in _FUNCTIONS:
        args = [_value(arg, values, where) for arg in node.args]
        try:
            with np.errstate(all="ignore"):
                return float(_FUNCTIONS[node.function](*args))
        except (TypeError, ValueError):  # a wrong number of arguments
            return math.nan
    raise ModelError(f"{where}: a requirement is arithmetic of constants with {sorted(_FUNCTIONS)}; "
                     "operators of fields have no value before the mesh")


def _holds(requirement: Requirement, values: dict[str, float]) -> bool:
    a = _value(requirement.left, values, requirement.where)
    b = _value(requirement.right, values, requirement.where)
    return bool(_TESTS[requirement.op](a, b))  # NaN fails every comparison


def _repair(requirement: Requirement, requirements: list[Requirement], values: dict[str, float],
            fixed: set[str]) -> tuple[str, float] | None:
    """A constant of ``requirement`` and a value for it that satisfies every requirement
    (the other constants as they are): its magnitude, then the numbers in the requirement and 1
    (each also doubled, plus one and halved), then 10× and 1/10 of the magnitude. None if none
    does."""
    numbers = [abs(node.value) for side in (requirement.left, requirement.right) for node in _numbers(side)]
    for name in sorted(requirement.names() - {"pi"} - fixed, key=lambda n: n not in names_in(requirement.left)):
        value = values[name]
        candidates = [abs(value)]
        for number in [*numbers, 1.0]:
            candidates += [number, 2 * number, number + 1, number / 2]
        candidates += [10 * abs(value), abs(value) / 10]
        for candidate in candidates:
            if candidate == value or not math.isfinite(candidate):
                continue
            trial = {**values, name: candidate}
            if all(_holds(other, trial) for other in requirements):
                return name, candidate
    return None


def _numbers(node: Node) -> list[Number]:
    if isinstance(node, Number):
        return [node]
    if isinstance(node, Negate):
        return _numbers(node.operand)
    if isinstance(node, Binary):
        return _numbers(node.left) + _numbers(node.right)
    if isinstance(node, Call):
        return [n for arg in node.args for n in _numbers(arg)]
    return []


def check_requirements(requirements: list[Requirement], values: dict[str, float], key: str = "app",
                       owners: dict[str, str] | None = None, fixed: dict[str, str] | None = None) -> None:
    """ModelError for the first requirement ``values`` (constants and ``dt``) violate, e.g.
    ``app.constants.Du=-1e-05 makes the model ill-posed: app.require[0] requires Du > 0 (a
    diffusivity); use `app.constants.Du=1e-05```. ``owners`` names the part each constant comes
    from (its default); ``fixed`` maps names that are not constants (``dt``) to their option key."""
    owners, fixed = owners or {}, fixed or {}
    for requirement in requirements:
        for name in requirement.names() - {"pi"}:  # unknown names: refused even while the requirement holds
            _value(Name(name), values, requirement.where)
        if _holds(requirement, values):
            continue
        names = sorted(requirement.names() - {"pi"})
        if not names:  # "1 > 2": no constant can make it hold
            listing = requirement.where.rsplit("[", 1)[0]
            raise ModelError(f"{requirement.where}: the requirement {requirement.text} reads no constant and is "
                             f"false, so no model can meet it; correct or remove it (`{listing}=[]`)")
        shown = ", ".join(f"{fixed.get(n, f'{key}.constants.{n}')}={values[n]:g}"
                          + (f" (part {owners[n]}'s)" if n in owners else "") for n in names)
        repair = _repair(requirement, requirements, values, set(fixed))
        if repair is not None:
            name, value = repair
            hint = f"; use `{key}.constants.{name}={value:g}`"
        else:
            hint = f"; set {' or '.join(fixed.get(n, f'{key}.constants.{n}') for n in names)} so that it holds"
        verb = "makes" if len(names) == 1 else "make"
        raise ModelError(f"{shown} {verb} the model ill-posed: {requirement.where} requires {requirement.text}{hint}")
