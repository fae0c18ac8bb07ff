"""A model made of parts that share fields by name (Decapodes' composition of Halfar's
equation with Glen's flow law through Γ and n).

A part is a piece of a model — fields, equations, metrics — and a composed model is its parts
and its own declarations merged (:func:`compose_parts`):

- a **field** declared by several parts is one field: their forms must agree, and its
  ``initial`` and ``dirichlet`` values are given by one of them (or equal);
- a **quantity** — what an equation computes (``dt(H) = …``, ``Gamma = …``) or a metric — is
  defined by one part only;
- equations are concatenated in part order, the model's own last (definitions are ordered by
  what they read when the model compiles, so the order is only that of the evolved fields).

Anything else is a :class:`ModelError` naming both parts. Constants are the model's parameters,
one value per name (``app.constants``, so a command-line override reaches them); a part gives
defaults for the ones it reads, and two parts' different defaults for one constant are refused
unless the model sets it (the model app, :mod:`decrun.apps.model`, which sees where each
value came from). No Hydra and no files here: the parts arrive as data.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from decrun.methods.model.language import ModelError, parse_equation

__all__ = ["PartSpec", "compose_parts"]


@dataclass
class PartSpec:
    """One part as data: ``fields`` name → an object with ``form``, ``initial``, ``dirichlet``
    (:class:`~decrun.methods.model.system.FieldSpec` or the app's options), ``equations`` (the
    strings of the model language) and ``metrics`` name → expression."""

    fields: dict[str, Any] = field(default_factory=dict)
    equations: list[str] = field(default_factory=list)
    metrics: dict[str, str] = field(default_factory=dict)


@dataclass
class Composed:
    """The merged model: ``fields`` name → (form, initial, dirichlet, neumann, robin); ``equations`` with the
    config key of each (``app.parts.glen_law.equations[0]``) for messages; ``metrics``."""

    fields: dict[str, tuple[Any, ...]]
    equations: list[str]
    equation_keys: list[str]
    metrics: dict[str, str]


def _form(value: Any) -> str:
    return str(value).strip()


def compose_parts(own: PartSpec, parts: dict[str, PartSpec], key: str = "app", own_name: str = "the model") -> Composed:
    """``parts`` (in order) then ``own`` merged into one model (module docstring); a conflict is a
    :class:`ModelError` naming both parts, e.g. ``app.parts: Gamma is computed by part glen_law
    (Gamma = …) and by part my_law (Gamma = …); a quantity has one definition: drop one``."""
    pieces = [(f"part {name}", f"{key}.parts.{name}", part) for name, part in parts.items()]
    pieces.append((own_name, key, own))
    fields: dict[str, tuple[Any, ...]] = {}
    field_owner: dict[str, dict[str, str]] = {}
    equations, equation_keys = [], []
    computed: dict[str, tuple[str, str]] = {}
    metrics: dict[str, str] = {}
    metric_owner: dict[str, str] = {}
    for who, where, part in pieces:
        for name, options in part.fields.items():
            value = (_form(options.form), options.initial, options.dirichlet, getattr(options, "neumann", None),
                     getattr(options, "robin", None))
            if name not in fields:
                fields[name] = value
                field_owner[name] = {"form": who, "initial": who, "dirichlet": who, "neumann": who, "robin": who}
                continue
            form = fields[name][0]
            if value[0] != form:
                raise ModelError(f"{key}.parts: field {name} is declared form {form} by {field_owner[name]['form']} "
                                 f"and form {value[0]} by {who}; a field shared by parts has one form")
            for index, what in ((1, "initial"), (2, "dirichlet"), (3, "neumann"), (4, "robin")):
                mine, theirs = value[index], fields[name][index]
                if mine is None or mine == theirs:
                    continue
                if theirs is not None:
                    raise ModelError(f"{key}.parts: field {name} gets its {what} value from "
                                     f"{field_owner[name][what]} ({theirs!r}) and from {who} ({mine!r}); give it once")
                fields[name] = tuple(mine if i == index else v for i, v in enumerate(fields[name]))
                field_owner[name][what] = who
        for i, text in enumerate(part.equations):
            where_i = f"{where}.equations[{i}]"
            equation = parse_equation(text, where_i)
            if equation.target:  # a solve's unknown is resolved when the model compiles (one equation per field)
                if equation.target in computed:
                    other, other_text = computed[equation.target]
                    raise ModelError(f"{key}.parts: {equation.target} is computed by {other} ({other_text.strip()}) "
                                     f"and by {who} ({str(text).strip()}); a quantity has one definition: drop one")
                computed[equation.target] = (who, str(text))
            equations.append(text)
            equation_keys.append(where_i)
        for name, text in part.metrics.items():
            if name in metrics and metrics[name] != text:
                raise ModelError(f"{key}.parts: metric {name} is {metrics[name]!r} in {metric_owner[name]} and "
                                 f"{text!r} in {who}; a metric has one definition: drop or rename one")
            metrics.setdefault(name, text)
            metric_owner.setdefault(name, who)
    return Composed(fields, equations, equation_keys, metrics)
