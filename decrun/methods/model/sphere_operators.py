"""The operators of rotating shallow water in the model language: TRiSK's energy-conserving
discretization (:mod:`decrun.core.trisk`) as typed operators of the registry.

TRiSK is DEC on the circumcentric dual: the depth h a primal 0-form (one value per Voronoi
cell = vertex), the velocity a primal 1-form U (the circulation along each edge), the mass flux a
dual 1-form G = ⋆1(h_e U), vorticity and potential vorticity dual 0-forms (one value per
triangle). With these the vector-invariant equations read (``conf/app/shallow_water.yaml``)::

    dt(depth) = -inv_star(d(mass_flux(depth, u)))
    dt(u) = -d(kinetic_energy(u) + g*(depth + b)) - coriolis((vorticity(u) + f)/kite_average(depth),
                                                             mass_flux(depth, u))

which is, term for term, the hand-written step of ``benchmarks/shallow_water_numpy.py``. Each
operator's matrices are TRiSK's, built once per :class:`~decrun.core.dec.DEC` and cached there.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.core.trisk import TRiSK
from decrun.methods.model.kinds import Kind, dual, primal

__all__ = ["built_in_operators", "trisk_of"]


def trisk_of(ops) -> TRiSK:
    """The :class:`TRiSK` operators of ``ops.dec``'s mesh, built once and cached on the DEC; a mesh that is
    not a sphere centred at the origin is refused first, in one line naming ``mesh=`` and the fix."""
    def build() -> TRiSK:
        require_sphere(ops.dec.K.vertices)
        return TRiSK(ops.dec)

    return ops.dec.require("trisk", build)


def require_sphere(vertices, rtol: float = 1e-9) -> float:
    """The radius of the sphere centred at the origin that holds ``vertices`` (n, 3), else one
    :class:`~decrun.errors.MeshError` line: the shallow-water operators are TRiSK's on a sphere."""
    from decrun.errors import MeshError

    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise MeshError(f"mesh: the shallow-water operators need a sphere in R³, got points in R^{vertices.shape[-1]}; "
                        "use mesh=icosphere_earth")
    distance = np.linalg.norm(vertices, axis=1)
    radius = float(distance.mean())
    worst = int(np.argmax(np.abs(distance - radius)))
    if not radius > 0 or abs(distance[worst] - radius) > rtol * radius:
        raise MeshError(f"mesh: not a sphere centred at the origin (vertex {worst} is {distance[worst]:.6g} from the "
                        f"origin, the mean {radius:.6g}): the shallow-water operators (TRiSK) need one; use "
                        "mesh=icosphere_earth (or mesh=icosphere mesh.noise=0 mesh.radius=<m>)")
    return radius


def _expect(name: str, kind: Kind, wanted: Kind, what: str) -> None:
    if kind != wanted:
        from decrun.methods.model.operators import Mismatch

        raise Mismatch(f"{name} takes {what}, got a {kind}")


def _triangles_only(name: str, n: int) -> None:
    if n != 2:
        from decrun.methods.model.operators import Mismatch

        raise Mismatch(f"{name} is defined on closed triangle meshes in R³ (TRiSK), not on dimension {n}")


# ------------------------------------------------------------------ mass_flux(h, u)
def _mass_flux_kind(args, n):
    _triangles_only("mass_flux", n)
    depth, velocity = args
    _expect("mass_flux", depth, primal(0), "a primal 0-form (the depth on the cells) first")
    _expect("mass_flux", velocity, primal(1), "a primal 1-form (the circulation U on the edges) second")
    return dual(1)


def _mass_flux_evaluate(ops, kinds, depth, velocity):
    return trisk_of(ops).mass_flux(depth, velocity)


def _mass_flux_derivative(ops, kinds, values, i):
    T = trisk_of(ops)
    depth, velocity = values
    if i == 0:  # ∂G/∂h = diag(⋆1 U) A_e (A_e the edge average)
        return (sp.diags(T.star1 * velocity) @ T.edge_average()).tocsr()
    return T.star1 * (T.edge_average() @ depth)  # ∂G/∂U = diag(⋆1 h_e)


# ------------------------------------------------------------------ kinetic_energy(u)
def _kinetic_kind(args, n):
    _triangles_only("kinetic_energy", n)
    _expect("kinetic_energy", args[0], primal(1), "a primal 1-form (the circulation U on the edges)")
    return primal(0)


def _kinetic_evaluate(ops, kinds, velocity):
    return trisk_of(ops).kinetic_energy(velocity)


def _kinetic_derivative(ops, kinds, values, i):
    return (trisk_of(ops).kinetic_matrix() @ sp.diags(2.0 * values[0])).tocsr()


# ------------------------------------------------------------------ vorticity(u)
def _vorticity_kind(args, n):
    _triangles_only("vorticity", n)
    _expect("vorticity", args[0], primal(1), "a primal 1-form (the circulation U on the edges)")
    return dual(0)


def _vorticity_linear(ops, kind):
    from decrun.methods.model.operators import Linear

    T = trisk_of(ops)
    return Linear(None, (sp.diags(1.0 / T.triangle_areas) @ ops.dec.d(1)).tocsr())


# ------------------------------------------------------------------ kite_average(h)
def _kite_kind(args, n):
    _triangles_only("kite_average", n)
    _expect("kite_average", args[0], primal(0), "a primal 0-form (values on the cells)")
    return dual(0)


def _kite_linear(ops, kind):
    from decrun.methods.model.operators import Linear

    return Linear(None, trisk_of(ops).cell_to_triangle())


# ------------------------------------------------------------------ coriolis(q, G)
def _coriolis_kind(args, n):
    _triangles_only("coriolis", n)
    pv, flux = args
    _expect("coriolis", pv, dual(0), "a dual 0-form (the potential vorticity on the triangles) first")
    _expect("coriolis", flux, dual(1), "a dual 1-form (the mass flux, e.g. mass_flux(depth, u)) second")
    return primal(1)


def _coriolis_evaluate(ops, kinds, pv, flux):
    T = trisk_of(ops)
    return T.coriolis_term(T.pv_on_edges(pv), flux)


def _coriolis_derivative(ops, kinds, values, i):
    T = trisk_of(ops)
    W, to_edges = T.perp(), T.triangle_to_edge()
    pv, flux = values
    if i == 0:  # ∂Q/∂q = ½ (diag(W G) + W diag(G)) (triangles → edges)
        return (0.5 * (sp.diags(W @ flux) + W @ sp.diags(flux)) @ to_edges).tocsr()
    qe = to_edges @ pv  # ∂Q/∂G = ½ (diag(q_e) W + W diag(q_e))
    return (0.5 * (sp.diags(qe) @ W + W @ sp.diags(qe))).tocsr()


def built_in_operators() -> list:
    """The shallow-water operators (:class:`~decrun.methods.model.operators.Operator`), registered as
    built-ins at the end of :mod:`decrun.methods.model.operators`."""
    from decrun.methods.model.operators import Operator

    return [
        Operator("mass_flux", (2,), "primal 0-form h, primal 1-form U → dual 1-form (triangles)",
                 "G = ⋆1 (h_e U), h_e = (h_i + h_j)/2: the volume flux l_e h_e u_e through each Voronoi edge "
                 "(TRiSK, Ringler et al. 2010); -inv_star(d(G)) is −∇·(h u) on the cells",
                 _mass_flux_kind, _mass_flux_evaluate, derivative=_mass_flux_derivative),
        Operator("kinetic_energy", (1,), "primal 1-form U → primal 0-form (triangles)",
                 "K_i = (1/(4 A_i)) Σ_{e∋i} ⋆1_e U_e² = (1/A_i) Σ_{e∋i} l_e d_e u_e²/4 on the Voronoi cells "
                 "(Ringler et al. 2010): Σ_i A_i K_i = Σ_e l_e d_e u_e²/2",
                 _kinetic_kind, _kinetic_evaluate, derivative=_kinetic_derivative),
        Operator("vorticity", (1,), "primal 1-form U → dual 0-form (triangles)",
                 "ζ_v = (d1 U)_v / A_v: the circulation around each triangle over its area (= star(d(u)); "
                 "ζ of d(φ) is 0 exactly)",
                 _vorticity_kind, lambda ops, kinds, x: _vorticity_linear(ops, kinds[0]).A @ x, _vorticity_linear),
        Operator("kite_average", (1,), "primal 0-form → dual 0-form (triangles)",
                 "h_v = Σ_{i∈v} A_{i,v} h_i / A_v, the circumcentric kite-weighted mean on each triangle "
                 "(TRiSK's depth at the vertices of the Voronoi grid; exact for constants)",
                 _kite_kind, lambda ops, kinds, x: _kite_linear(ops, kinds[0]).A @ x, _kite_linear),
        Operator("coriolis", (2,), "dual 0-form q, dual 1-form G → primal 1-form (triangles)",
                 "Q_e = ½ (q_e (W G)_e + (W (q_e G))_e), q_e = (q_v + q_v')/2, W TRiSK's antisymmetric "
                 "primal–dual weights (Thuburn et al. 2009): ≈ ∫_e q (h u)^⊥·dl, and Σ_e G_e Q_e = 0 for "
                 "every q, G (the Coriolis force does no work)",
                 _coriolis_kind, _coriolis_evaluate, derivative=_coriolis_derivative),
    ]

