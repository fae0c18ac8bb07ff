"""The border terms of ``app.explain`` shown as what they are.

A Neumann or Robin border rewrites ``laplacian(u)`` with names of its own
(:func:`decrun.methods.model.borders.rewrite`): ``laplacian(u) + inv_star(_neumann_u)``, or
``laplacian(u) - _robin_alpha_u*u + inv_star(_robin_value_u)``. Those internal names mean nothing to the
person who wrote ``app.fields.u.neumann``; :func:`relabel` shows them in the explained model as

- ``neumann_load(u)``: b, b_i = ∫_{Γ_i} g, the Neumann load (∂u/∂n = g), a dual n-form;
- ``robin_load(u)``: b, b_i = ∫_{Γ_i} v, the Robin load (∂u/∂n + α u = v), a dual n-form;
- ``robin_weight(u)``: (∫_{Γ_i} α) / ⋆0_i, the Robin coefficient, a primal 0-form;

(Γ_i the part of the border in vertex i's dual cell) with one legend line each naming the config
key and the expression given there. Only the text changes: the compiled model keeps its names.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from decrun.methods.model.borders import internal_roles
from decrun.methods.model.language import names_in, parse_expression

__all__ = ["labels", "legend", "relabel"]

_LABELS = {"neumann": "neumann_load", "robin.value": "robin_load", "robin.alpha": "robin_weight"}


def labels(spec) -> dict[str, str]:
    """``{internal name: label}``, e.g. ``{"_neumann_u": "neumann_load(u)"}`` (module docstring)."""
    return {internal: f"{_LABELS[part]}({field})" for internal, (field, part) in internal_roles(spec).items()}


def _given(spec, field: str, part: str):
    """The expression given at ``app.fields.<field>.<part>`` (as written: a string or a number)."""
    if part == "neumann":
        return spec.fields[field].neumann
    robin = spec.fields[field].robin
    return robin.get(part.split(".")[1]) if isinstance(robin, Mapping) else robin


def legend(spec, kinds: Mapping) -> list[str]:
    """One line per border term: its label, kind and meaning, and the key and expression it
    comes from (and whether it is evaluated again at every step: it reads t)."""
    lines = []
    for internal, (field, part) in internal_roles(spec).items():
        label, key = f"{_LABELS[part]}({field})", f"{spec.key}.fields.{field}.{part}"
        given = _given(spec, field, part)
        kind = f" : {kinds[internal]}" if internal in kinds else ""
        if part == "neumann":
            meaning = (f"b_i = ∫_Γi g, the Neumann load of {field} (∂{field}/∂n = g, g = {key} = {given}); "
                       f"laplacian({field}) + inv_star({label}) is ⋆0⁻¹(−S {field} + b)")
        elif part == "robin.value":
            meaning = f"b_i = ∫_Γi v, the Robin load of {field} (∂{field}/∂n + α {field} = v, v = {key} = {given})"
        else:
            meaning = (f"(∫_Γi α) / ⋆0_i, the Robin coefficient of {field} (α = {key} = {given}); "
                       f"laplacian({field}) - {label}*{field} is ⋆0⁻¹(−(S + R) {field}), R = diag(∫_Γi α)")
        if isinstance(given, str) and "t" in names_in(parse_expression(given, key)):
            meaning += "; it reads t: evaluated again at every step"
        lines.append(f"  {label}{kind}: {meaning}")
    if lines:
        lines.insert(0, "border terms (Γi: the part of the border in vertex i's dual cell):")
    return lines


def relabel(text: str, spec) -> str:
    """``text`` with every internal border name (a whole word) replaced by its label."""
    names = labels(spec)
    if not names:
        return text
    pattern = re.compile(r"(?<![A-Za-z0-9_])(" + "|".join(re.escape(name) for name in sorted(names, key=len,
                                                                                              reverse=True))
                         + r")(?![A-Za-z0-9_])")
    return pattern.sub(lambda match: names[match.group(1)], text)
