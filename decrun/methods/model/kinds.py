"""The types of the model language: a primal or dual k-form, a number, or a vector field.

Every value a model computes has one :class:`Kind`, checked when the model loads:

- a **primal k-form** holds one number per k-simplex of ``K.simplices(k)`` (n_k values);
- a **dual k-form** one number per dual k-cell, i.e. per (n−k)-simplex (n_{n−k} values; a dual
  0-form is one value per top simplex, at its circumcentre);
- a **number** is one float (constants, ``t``, ``dt``, ``integral(u)``);
- a **vector** is one vector per top simplex, ``(n_n, d)`` (``sharp(d(u))``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from decrun.methods.model.language import ModelError

__all__ = ["Kind", "NUMBER", "VECTOR", "primal", "dual", "form_kind"]


@dataclass(frozen=True)
class Kind:
    """``what``: ``form`` | ``number`` | ``vector``; ``degree`` and ``dual`` for forms."""

    what: str
    degree: int = 0
    dual: bool = False

    @property
    def is_form(self) -> bool:
        return self.what == "form"

    def simplex_dimension(self, n: int) -> int:
        """The dimension of the simplices that carry the form's values (k primal, n−k dual)."""
        return n - self.degree if self.dual else self.degree

    def size(self, K) -> int:
        """How many values the form has on ``K``."""
        return K.num_simplices(self.simplex_dimension(K.dim))

    def __str__(self) -> str:
        if self.what == "form":
            return f"{'dual' if self.dual else 'primal'} {self.degree}-form"
        if self.what == "vector":
            return "vector field (one vector per top simplex)"
        return "number"

    def spec(self) -> str:
        """As written in ``fields.<name>.form``: ``0`` … ``3``, ``dual0`` … ``dual3``."""
        return f"dual{self.degree}" if self.dual else str(self.degree)


NUMBER = Kind("number")
VECTOR = Kind("vector")


def primal(k: int) -> Kind:
    return Kind("form", int(k), False)


def dual(k: int) -> Kind:
    return Kind("form", int(k), True)


def form_kind(spec, where: str, n: int | None = None) -> Kind:
    """``fields.<name>.form`` → Kind: ``0 | 1 | 2 | 3`` (primal) or ``dual0 | dual1 | dual2 |
    dual3``, or a degree relative to the mesh dimension n — ``n`` (the top degree: a density,
    one value per top simplex) and ``n-1`` … ``n-3`` (``n-1``: a flux through the (n−1)-simplices,
    edges of triangles or faces of tetrahedra), primal or ``dualn``/``dualn-1`` — so one model
    runs on triangle and tetrahedral meshes. With ``n`` (the mesh dimension) the degree is checked
    against it; a relative degree needs it."""
    text = str(spec).strip().lower().replace(" ", "").replace("_", "")
    is_dual = text.startswith("dual")
    digits = text[4:] if is_dual else text
    if text.startswith("primal"):
        digits = text[6:]
    relative = re.fullmatch(r"n(?:-([0-3]))?", digits)
    if relative:
        if n is None:
            raise ModelError(f"{where}: the form {spec!r} is relative to the mesh dimension, which is not known here")
        below = int(relative.group(1) or 0)
        if below > n:
            raise ModelError(f"{where}: a form of degree {spec} does not exist on a mesh of dimension {n}")
        digits = str(n - below)
    if not (digits.isdigit() and 0 <= int(digits) <= 3):
        raise ModelError(f"{where}: form must be 0 | 1 | 2 | 3 (primal), dual0 | dual1 | dual2 | dual3, or relative to "
                         f"the mesh dimension n: n | n-1 | n-2 (dualn …), got {spec!r}")
    kind = Kind("form", int(digits), is_dual)
    if n is not None and kind.degree > n:
        raise ModelError(f"{where}: a {kind} does not exist on a mesh of dimension {n} (degrees 0..{n})")
    return kind
