"""Arithmetic of numbers in the model language: numpy's semantics, never Python's exceptions.

A model's numbers — constants, ``t``, ``dt``, ``h``, literals, ``integral(u)`` — are float64
scalars, and arithmetic between two of them follows IEEE 754 as numpy does for arrays: ``1/0`` is
inf, ``0/0`` nan, ``k**1e308`` inf. Python's floats would raise ``ZeroDivisionError`` or
``OverflowError`` instead, so that a metric ``integral(u)/t`` at t = 0 lost the whole run (issue
50, item 8). A non-finite number is then caught by the checks that follow it (a non-finite
metric makes the run ``stable: false``, naming the metric; a non-finite coefficient is refused
where it is used)."""

from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["number_arithmetic"]

_OPERATIONS: dict[str, Callable] = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide,
                                    "**": np.power}


def number_arithmetic(op: str, left: Callable, right: Callable) -> Callable:
    """The closure ``env ↦ left(env) op right(env)`` of two numbers (``op`` one of ``+ - * / **``),
    as a float64 scalar with IEEE 754 results (inf, nan) where Python raises."""
    operation = _OPERATIONS[op]

    def number(env):
        with np.errstate(all="ignore"):
            return operation(np.float64(left(env)), np.float64(right(env)))
    return number
