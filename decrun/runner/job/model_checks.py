"""Checks of a declarative model's config that need only the config, run for every run and
every planned job of a sweep before anything runs (:class:`~decrun.runner.job.experiment.Experiment`):

- a constant the command line adds is read by an equation, a metric, a requirement, an initial
  or border value or a figure — a misspelt ``+app.constants.epz=0.1`` would otherwise run
  silently with the default ``eps`` (:func:`decrun.runner.command.model_keys.refuse_unread_constants`);
- ``t_end`` is a whole number of steps of ``dt`` (:meth:`decrun.apps.model.Model.total_steps`),
  so a sweep of ``app.dt`` is refused at planning, not when its odd job runs.

The names a text reads come from the model language's own parser
(:func:`decrun.methods.model.language.parse_expression`, ``names_in``)."""

from __future__ import annotations

import difflib
import functools
from collections.abc import Mapping
from typing import Any, Collection

from decrun.errors import ConfigError, DecrunError
from decrun.methods.model.language import names_in, parse_equation, parse_expression
from decrun.methods.model.require import parse_requirement

__all__ = ["names_read", "check_model"]


def _texts(value: Any) -> list[str]:
    """The strings in an option value (a string, a list of them for a vector field; numbers: none)."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, (list, tuple)):
        return [text for item in value for text in _texts(item)]
    return []


def _expression_names(text: str) -> set[str]:
    """The names an expression reads; none for a text that is not one (``random``,
    ``result:u``: the model's own checks say what is wrong with it)."""
    try:
        return names_in(parse_expression(text, "app"))
    except DecrunError:
        return set()


def names_read(app: Any) -> set[str]:
    """Every name the model ``app`` (:class:`decrun.apps.model.Model`) reads: in its equations,
    metrics, requirements, fields' initial and border values and figures, its parts' included."""
    equations: list[str] = []
    expressions: list[str] = []
    requirements: list[str] = []
    for source in (app, *app.parts.values()):
        equations += [str(text) for text in source.equations]
        expressions += [str(text) for text in source.metrics.values()]
        requirements += [str(text) for text in source.require]
        for options in source.fields.values():
            expressions += _texts(options.initial) + _texts(options.dirichlet)
            robin = getattr(options, "robin", None)  # Neumann / Robin borders (methods/model/borders.py)
            expressions += _texts(getattr(options, "neumann", None)) + \
                _texts(list(robin.values()) if isinstance(robin, Mapping) else robin)
    for plot in app.plots.values():
        expressions += [text for text in (plot.color, plot.arrows) if text]
    return set(_names(tuple(equations), tuple(expressions), tuple(requirements)))


@functools.lru_cache(maxsize=256)
def _names(equations: tuple[str, ...], expressions: tuple[str, ...], requirements: tuple[str, ...]) -> frozenset:
    """The names read by these texts, parsed once per distinct model (a sweep checks every job)."""
    read: set[str] = set()
    for text in equations:
        try:
            equation = parse_equation(text, "app.equations")
        except DecrunError:  # the model's own checks say what is wrong with it
            continue
        for left, right in equation.pairs or ((equation.lhs, equation.rhs),):
            read |= (names_in(left) if left is not None else set()) | names_in(right)
    for text in expressions:
        read |= _expression_names(text)
    for text in requirements:
        try:
            read |= parse_requirement(text, "app.require").names()
        except DecrunError:
            continue
    return frozenset(read)


def check_model(app: Any, added: Collection[str] = ()) -> None:
    """ConfigError for a constant of ``added`` (those the command line adds, ``+app.constants.<name>=…``)
    that nothing in the model ``app`` reads, naming the closest one that is read (the fix); and for a
    ``t_end`` that is not a whole number of ``dt``. A constant the model's own file declares and
    an override of the initial value no longer reads stays allowed."""
    read = names_read(app) if added else set()
    for name in added:
        if name not in app.constants or name in read:
            continue
        used = sorted(c for c in app.constants if c in read)
        close = difflib.get_close_matches(name, used, n=1)
        fix = f"; did you mean app.constants.{close[0]}?" if close else \
            f"; drop it (its constants: {', '.join(used) or 'none'})"
        raise ConfigError(f"app.constants.{name}: unknown constant of app={app.model} (no equation, metric or "
                          f"requirement reads it){fix}")
    app.total_steps()
