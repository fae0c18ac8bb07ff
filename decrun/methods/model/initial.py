"""Initial (and Dirichlet) values of a model's fields, sampled from expressions (thesis §3.2).

A value is given as

- a number: that value on every simplex that carries the form;
- an expression of ``x, y, z`` (and constants, ``pi``, ``random``: uniform in [−1, 1], seeded)
  for a 0-form, evaluated at the vertices; for a top form (a density ρ) integrated over each top
  simplex, ∫_σ ρ dV (order-2 quadrature, :func:`decrun.core.forms.sample_density`); for a dual
  0-form evaluated at the circumcentres of the top simplices; for a dual k-form, ⋆ of the
  primal (n−k)-form sampled from the same expression;
- a list of ``d`` expressions, a vector field X: for a 1-form its line integral along each edge
  ∫_e X·t ds by Gauss–Legendre quadrature exact for polynomials of degree ≤ 9 along the edge
  (so the 1-form of X = ∇φ is d of φ's 0-form to round-off); for a 2-form in R³ its flux through
  each triangle (:func:`decrun.core.forms.sample_flux`);
- ``{flux: [X_1, …, X_d]}``, for a primal (n−1)-form on any mesh: the flux of the vector field X
  through each (n−1)-simplex, ∫_σ i_X vol — through the faces of tetrahedra (as a 2-form's list),
  across the edges of triangles ∫_e (N × X)·t ds with N the unit normal of the oriented triangles
  at the edge (the circulation of X turned by 90° in the surface), so that d of it is the integral
  of div X over each top simplex (Stokes) — the flux of a velocity, for one model on triangles and
  tetrahedra (``app=darcy``);
- ``vertex(i)``: the indicator of vertex i (0-forms);
- ``latitude_integral(F)`` inside an expression: ∫_{−π/2}^{θ} F dθ' of a function F of the latitude, its sphere
  mean removed (:mod:`decrun.methods.model.sphere_functions`);
- ``{spherical_harmonics: <file.npz>, coefficients: <array>}``: a stored spectral field (its sha256 checked
  against the manifest beside it) at the vertices or circumcentres (:mod:`decrun.methods.spherical_harmonics`);
- ``result:<field>``: the field of a previous run, chained with ``mesh=result mesh.field=<field>``.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping
from typing import Any

import numpy as np

from decrun.core.forms import sample_density, sample_flux, sample_vector_field
from decrun.methods.model.compiler import Compiler
from decrun.methods.model.kinds import NUMBER, Kind, primal
from decrun.methods.model.language import (
    Binary,
    Call,
    ModelError,
    Name,
    Negate,
    Node,
    Number,
    parse_expression,
    to_text,
)
from decrun.methods.model.operators import OPERATORS, Discrete
from decrun.methods.model.sphere_functions import latitude_integral

__all__ = ["sample", "PointExpression"]

#: Gauss–Legendre points along an edge: exact for polynomials of degree ≤ 2·5 − 1 = 9
EDGE_QUADRATURE = 5


class PointExpression:
    """A value-by-value expression of the coordinates, checked against the whitelist (numbers,
    ``x y z pi random``, constants, + − * / **, the one-argument functions, two-argument
    min/max, ``vertex(i)``) and evaluated at any points by the model's one evaluator
    (:meth:`decrun.methods.model.compiler.Compiler.compile`, the closures equations and metrics
    run), with ``x y z random`` the values at the points."""

    def __init__(self, text, where: str, constants: dict[str, float], dec):
        self.where, self.constants = where, constants
        self.tree = parse_expression(text, where)
        self._check(self.tree)
        self.integrals: list[tuple[str, PointExpression]] = []
        tree = self._lift_integrals(self.tree, dec)
        kinds = {name: NUMBER for name in constants}
        kinds["random"] = primal(0)
        lifted = {name for name, _ in self.integrals}
        kinds.update(dict.fromkeys(lifted, primal(0)))
        compiler = Compiler(Discrete(dec), kinds, varying={"x", "y", "z", "random", *lifted})
        compiler.static_env = {"pi": float(np.pi), **{k: float(v) for k, v in constants.items()}}
        self.evaluate = compiler.compile(tree, where)

    def _lift_integrals(self, node: Node, dec) -> Node:
        """``latitude_integral(F)`` needs F on meridians, not at the points: each is replaced by a
        name that :meth:`at` binds to :func:`~decrun.methods.model.sphere_functions.latitude_integral`
        of F (its own expression)."""
        if isinstance(node, Negate):
            return Negate(self._lift_integrals(node.operand, dec))
        if isinstance(node, Binary):
            return Binary(node.op, self._lift_integrals(node.left, dec), self._lift_integrals(node.right, dec))
        if not isinstance(node, Call):
            return node
        if node.function != "latitude_integral":
            return Call(node.function, tuple(self._lift_integrals(arg, dec) for arg in node.args))
        from decrun.methods.model.language import names_in

        if "random" in names_in(node.args[0]):
            raise ModelError(f"{self.where}: latitude_integral(F) integrates a function of the latitude; F may not "
                             "use random")
        name = f"_latitude_integral_{len(self.integrals)}"
        self.integrals.append((name, PointExpression(to_text(node.args[0]), self.where, self.constants, dec)))
        return Name(name)

    def _check(self, node: Node) -> None:
        if isinstance(node, Number):
            return
        if isinstance(node, Name):
            if node.name not in {"x", "y", "z", "pi", "random"} | set(self.constants):
                import difflib

                close = difflib.get_close_matches(node.name, ["x", "y", "z", "pi", "random", *self.constants], n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ModelError(f"{self.where}: unknown name {node.name!r}{hint}; a value is an expression of x, y, z, "
                                 "pi, random and app.constants")
            return
        if isinstance(node, Negate):
            return self._check(node.operand)
        if isinstance(node, Binary):
            if node.op == "^":
                raise ModelError(f"{self.where}: ^ (the wedge) is not a value; use ** for powers in {to_text(node)!r}")
            self._check(node.left)
            self._check(node.right)
            return
        if isinstance(node, Call):
            operator = OPERATORS.get(node.function)  # the registry's value-by-value operators (plugins' too)
            allowed = operator is not None and operator.pointwise and len(node.args) in operator.arity and \
                (node.function not in ("min", "max") or len(node.args) == 2) or \
                node.function in ("vertex", "latitude_integral") and len(node.args) == 1
            if not allowed:
                raise ModelError(f"{self.where}: {to_text(node)}: an initial or border value is an expression of the "
                                 "coordinates (exp, sin, sqrt … of x, y, z); operators such as laplacian belong in "
                                 "app.equations")
            for arg in node.args:
                self._check(arg)
            return
        raise TypeError(node)

    def uses(self, name: str) -> bool:
        from decrun.methods.model.language import names_in

        return name in names_in(self.tree)

    def has_vertex(self, node: Node | None = None) -> bool:
        node = self.tree if node is None else node
        if isinstance(node, Call):
            return node.function == "vertex" or any(self.has_vertex(arg) for arg in node.args)
        if isinstance(node, Binary):
            return self.has_vertex(node.left) or self.has_vertex(node.right)
        if isinstance(node, Negate):
            return self.has_vertex(node.operand)
        return False

    def at(self, points: np.ndarray, rng: np.random.Generator, n_vertices: int | None = None) -> np.ndarray:
        """(N,) values at ``points`` (N, d); ``n_vertices`` set when the points are the vertices
        (``vertex(i)`` is only defined there)."""
        points = np.asarray(points, dtype=np.float64)
        env = self._environment(points)
        if self.uses("random"):
            env["random"] = rng.uniform(-1.0, 1.0, len(points))
        for name, integrand in self.integrals:  # F on the meridians, integrated in the latitude
            with np.errstate(all="ignore"):
                env[name] = latitude_integral(integrand.on, points, self.where)
        if n_vertices is None and self.has_vertex():
            raise ModelError(f"{self.where}: vertex(i) is a 0-form (an indicator at a vertex); use it for a field "
                             "with form: 0")
        value: Any
        try:
            with np.errstate(all="ignore"):
                value = self.evaluate(env)
        except (ZeroDivisionError, OverflowError):  # numbers alone (Python floats): not finite anywhere
            value = np.nan
        if np.iscomplexobj(value):  # a negative number to a fractional power
            value = np.nan
        out = np.broadcast_to(np.asarray(value, dtype=np.float64), (len(points),)).copy()
        bad = ~np.isfinite(out)
        if bad.any():
            index = int(np.flatnonzero(bad)[0])
            raise ModelError(f"{self.where}: the value is not finite at {int(bad.sum())} of {len(out)} points (e.g. at "
                             f"{np.round(points[index], 6).tolist()}); change the expression there")
        return out

    def on(self, points: np.ndarray) -> np.ndarray:
        """The values at ``points`` (N, 3) with no check (a latitude integral's integrand, checked
        by :func:`~decrun.methods.model.sphere_functions.latitude_integral`)."""
        return np.asarray(self.evaluate(self._environment(np.asarray(points, dtype=np.float64))), dtype=np.float64)

    def _environment(self, points: np.ndarray) -> dict:
        return {"x": points[:, 0], "y": points[:, 1] if points.shape[1] > 1 else np.zeros(len(points)),
                "z": points[:, 2] if points.shape[1] > 2 else np.zeros(len(points)), "pi": np.pi,
                **{k: float(v) for k, v in self.constants.items()}}


def _rng(seed: int, name: str) -> np.random.Generator:
    """A generator seeded by the model's seed and the field's name (the same every run)."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(name.encode())])


def sample(value, kind: Kind, dec, where: str, *, constants: dict[str, float], seed: int = 0, name: str = "",
           chained: dict | None = None) -> np.ndarray:
    """The values (n_simplices,) of a field of ``kind`` from ``value`` (see the module docstring)."""
    K = dec.K
    n, size = K.dim, kind.size(K)
    rng = _rng(seed, name)
    if isinstance(value, str) and value.strip().startswith("result:"):
        return _chained(value.strip()[len("result:"):].strip(), kind, K, where, chained)
    if isinstance(value, (list, tuple)):
        return _vector(value, kind, dec, where, constants, rng)
    if isinstance(value, Mapping) and "spherical_harmonics" in value:
        return _spherical_harmonics(value, kind, dec, where)
    if isinstance(value, Mapping):
        return _flux(value, kind, dec, where, constants, rng)
    if isinstance(value, bool):
        raise ModelError(f"{where}: expected a number or an expression, got {value!r}")
    if isinstance(value, (int, float)):
        if not np.isfinite(value):
            raise ModelError(f"{where}: must be a finite number, got {value}")
        return np.full(size, float(value))
    expression = PointExpression(value, where, constants, dec)
    if kind.dual and kind.degree == 0:  # one value per top simplex, at its circumcentre
        return expression.at(dec.circumcenters(n), rng)
    if kind.dual:  # ⋆ of the primal (n−k)-form of the same expression
        primal_values = sample(value, primal(n - kind.degree), dec, where, constants=constants, seed=seed, name=name)
        return dec.star(n - kind.degree) @ primal_values
    if kind.degree == 0:
        return expression.at(K.vertices, rng, n_vertices=K.num_simplices(0))
    if expression.has_vertex():
        raise ModelError(f"{where}: vertex(i) is a 0-form; a {kind} takes a number or an expression")
    if kind.degree == n:
        return sample_density(K, lambda points: expression.at(points, rng), order=2)  # on the oriented simplices
    example = '["-y", "x", "0"]' if K.embedding_dim == 3 else '["-y", "x"]'
    what = "line integral along each edge" if kind.degree == 1 else "flux through each face"
    raise ModelError(f"{where}: a {kind} is sampled from a vector field: give a list of {K.embedding_dim} expressions "
                     f"(e.g. {example}), its {what}")


def _spherical_harmonics(value, kind: Kind, dec, where: str) -> np.ndarray:
    """``{spherical_harmonics: <file.npz>, coefficients: <array>}``: the stored real field at the vertices
    (a 0-form) or the circumcentres (a dual 0-form) of a mesh in R³
    (:func:`decrun.methods.spherical_harmonics.evaluate_real_field`)."""
    from decrun.methods.spherical_harmonics import evaluate_real_field, load_coefficients

    K = dec.K
    if set(value) != {"spherical_harmonics", "coefficients"}:
        raise ModelError(f"{where}: a stored spectral field is {{spherical_harmonics: <file.npz>, coefficients: "
                         f"<array>}}, got the keys {sorted(value)}")
    if K.embedding_dim != 3 or not (kind == primal(0) or kind.dual and kind.degree == 0):
        raise ModelError(f"{where}: a spherical-harmonic field is a 0-form or dual 0-form on a mesh in R³, not a {kind}")
    alm, lmax = load_coefficients(str(value["spherical_harmonics"]), str(value["coefficients"]), where)
    points = K.vertices if kind == primal(0) else dec.circumcenters(K.dim)
    return evaluate_real_field(alm, lmax, points)


def _vector(value, kind: Kind, dec, where: str, constants, rng) -> np.ndarray:
    K = dec.K
    d = K.embedding_dim
    if len(value) != d:
        raise ModelError(f"{where}: a vector field has {d} components on this mesh (its coordinates' dimension), got "
                         f"{len(value)}")
    parts = [PointExpression(item, f"{where}[{i}]", constants, dec) for i, item in enumerate(value)]

    def field(points):
        return np.stack([part.at(points, rng) for part in parts], axis=1)

    if kind.dual:
        primal_values = _vector(value, primal(K.dim - kind.degree), dec, where, constants, rng)
        return dec.star(K.dim - kind.degree) @ primal_values
    if kind.degree == 1:
        return sample_vector_field(K, field, order=EDGE_QUADRATURE)
    if kind.degree == 2 and d == 3:
        flux = sample_flux(K, field, order=2)
        return flux * K.orientation if K.dim == 2 else flux
    raise ModelError(f"{where}: a {kind} is not sampled from a vector field; give a number or an expression")


def _flux(value, kind: Kind, dec, where: str, constants, rng) -> np.ndarray:
    """The (n−1)-form of ``{flux: [X_1, …, X_d]}``: ∫_σ i_X vol over each (n−1)-simplex σ (module
    docstring), in the orientation of σ's sorted tuple, which the incidence ``d_{n−1}`` uses."""
    K = dec.K
    n, d = K.dim, K.embedding_dim
    if set(value) != {"flux"}:
        raise ModelError(f"{where}: a mapping gives a flux, {{flux: [X_1, …, X_{d}]}}; got the keys {sorted(value)}")
    if kind.dual or kind.degree != n - 1 or n not in (2, 3):
        raise ModelError(f"{where}: {{flux: […]}} samples a primal (n−1)-form (form: n-1) on triangles or tetrahedra, "
                         f"not a {kind} on a mesh of dimension {n}")
    items = list(value["flux"])
    # on triangles in a plane the component along the normal has no flux across the edges, so a
    # three-component field is read on planar (2-D) coordinates too: one model file for both
    allowed = {d, 3} if n == 2 else {d}
    if len(items) not in allowed:
        raise ModelError(f"{where}.flux: a vector field has {' or '.join(map(str, sorted(allowed)))} components on "
                         f"this mesh, got {len(items)}")
    parts = [PointExpression(item, f"{where}.flux[{i}]", constants, dec) for i, item in enumerate(items)]

    def field(points):
        return np.stack([part.at(points, rng) for part in parts], axis=1)

    if n == 3:
        return sample_flux(K, field, order=2)
    corners = K.vertices[K.oriented_simplices()]
    if d == 2:  # planar coordinates: N = ±e_z, N × X = (−N_z X_y, N_z X_x)
        first, second = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
        sign = np.sign(first[:, 0] * second[:, 1] - first[:, 1] * second[:, 0])
        normals = np.zeros((len(sign), 3))
        normals[:, 2] = sign
    else:
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        normals /= np.linalg.norm(normals, axis=1)[:, None]
    table = K.top_face_indices(1)
    edge_normals = np.zeros((K.num_simplices(1), 3))
    for slot in range(table.shape[1]):
        np.add.at(edge_normals, table[:, slot], normals)
    edge_normals /= np.linalg.norm(edge_normals, axis=1)[:, None]
    nodes, weights = np.polynomial.legendre.leggauss(EDGE_QUADRATURE)
    edges = K.simplices(1)
    start, direction = K.vertices[edges[:, 0]], K.vertices[edges[:, 1]] - K.vertices[edges[:, 0]]
    points = start[:, None, :] + 0.5 * (nodes + 1.0)[None, :, None] * direction[:, None, :]
    values = field(points.reshape(-1, d)).reshape(len(edges), EDGE_QUADRATURE, len(items))
    if len(items) == 2:
        values = np.concatenate([values, np.zeros(values.shape[:2] + (1,))], axis=2)
    if d == 2:
        direction = np.concatenate([direction, np.zeros((len(edges), 1))], axis=1)
    turned = np.cross(edge_normals[:, None, :], values)  # N × X at every quadrature point
    return np.einsum("q,eqd,ed->e", 0.5 * weights, turned, direction)


def _chained(field: str, kind: Kind, K, where: str, chained: dict | None) -> np.ndarray:
    if not chained:
        raise ModelError(f"{where}: result:{field} takes the field of a previous run: add `mesh=result "
                         f"mesh.path=<run>/result.h5 mesh.field={field}`")
    if chained.get("name") != field:
        raise ModelError(f"{where}: result:{field}, but the chained mesh carries the field {chained.get('name')!r}; "
                         f"use `mesh.field={field}`")
    values = np.asarray(chained["values"], dtype=np.float64)
    size = kind.size(K)
    if values.shape != (size,):
        raise ModelError(f"{where}: result:{field} has shape {values.shape}, but a {kind} on this mesh has {size} "
                         f"values (it lives on {chained.get('on')})")
    if not np.all(np.isfinite(values)):
        raise ModelError(f"{where}: result:{field} has {int((~np.isfinite(values)).sum())} non-finite values")
    return values
