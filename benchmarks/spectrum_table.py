"""The spectrum table of docs/apps/spectrum.md: relative error of the first 10 eigenvalues of Δ_k against
the analytic spectrum, per mesh, Hodge-star variant and degree k.

Meshes: the unit icosphere (subdiv 3), the flat torus 2π × 2π (24 × 24 periodic grid in R⁴),
the unit square (16 × 16 grid, interior jitter 0.2), the unit cube (6³ Kuhn cells) and the
unit ball (TetGen, surface kept on the sphere, max volume 0.002; functions only).

Cells: ``eigenvalue_relative_error_max`` over the nonzero analytic eigenvalues; ``zero ⋆``
where the variant's ⋆_{k-1} or ⋆_k has zero entries and the run is refused; ``⋆ < 0`` where
the mass ⋆_k (an indefinite pencil) or a stiffness ⋆_{k±1} inside Δ_k (an indefinite operator)
has negative entries: refused; ``†`` where ⋆_k has zero
entries (a semi-definite mass: the Arnoldi solve); ``n/a`` where the variant has no operators for k;
``R³ only`` where the variant's geometry needs vertices in R³ (the torus lives in R⁴).

    python benchmarks/spectrum_table.py

``scripts/doc_numbers.py`` takes the page's cells from :func:`table` (checked by tests/test_numbers.py).
"""

from __future__ import annotations

import numpy as np

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.primitives import flat_torus, grid_triangles, kuhn_cube
from decrun.core.stars.whitney import Whitney
from decrun.errors import DecrunError
from decrun.methods.spectrum import analytic_spectrum, detect_domain, laplacian_eigenpairs, spectrum_errors

VARIANTS = ["circumcentric", "barycentric", "mixed_area", "whitney", "whitney_lumped", "intrinsic_delaunay"]


def meshes():
    """(key, label, vertices, simplices, degrees) of the five meshes of the table."""
    import pymeshlab

    from decrun.runner.mesh.sources.volumes import tetrahedralize_surface

    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=1.0, subdiv=3)
    sphere = ms.current_mesh()
    V = sphere.vertex_matrix()
    V = V / np.linalg.norm(V, axis=1, keepdims=True)
    yield "sphere", "sphere (642 vertices)", V, sphere.face_matrix().astype(np.int64), (0, 1, 2)
    yield "torus", "flat torus (576 vertices)", *flat_torus(24), (0, 1, 2)
    yield "square", "square (289 vertices, jittered)", *grid_triangles(16, jitter=0.2), (0, 1, 2)
    yield "cube", "cube (343 vertices, Kuhn)", *kuhn_cube(6), (0, 1, 2, 3)
    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=1.0, subdiv=2)
    surface = ms.current_mesh()
    SV = surface.vertex_matrix()
    SV = SV / np.linalg.norm(SV, axis=1, keepdims=True)
    nodes, tets, _ = tetrahedralize_surface(SV, surface.face_matrix(), max_volume=0.002, keep_surface=True)
    yield "ball", f"ball ({len(nodes)} vertices, TetGen)", nodes, tets, (0,)


def star(name):
    return Whitney(lumped=True) if name == "whitney_lumped" else name


def measure(K, variant, k):
    """``(error, positive)``: ``eigenvalue_relative_error_max`` of the first 10 eigenvalues of Δ_k
    with this variant's stars and whether ⋆_k is positive (False: the Arnoldi solve); or the
    reason the cell has no number (a string: ``zero ⋆``, ``⋆ < 0``, ``n/a``, ``R³ only``)."""
    try:
        dec = DEC(K, star=star(variant))
        degrees = dec.star_variant.form_degrees
        if degrees is not None and k > 0:
            return "n/a"
        pairs = laplacian_eigenpairs(dec, k, 10)
    except DecrunError as exc:
        return "zero ⋆" if "zero on" in str(exc) else "⋆ < 0" if "positive mass" in str(exc) or \
            "indefinite" in str(exc) else f"refused ({str(exc)[:40]}…)"
    except ValueError:  # mixed_area / intrinsic_delaunay compute in R³: not for the torus in R⁴
        return "R³ only"
    domain = detect_domain(K)
    errors = spectrum_errors(pairs.values, analytic_spectrum(domain, k, 10))
    return float(errors["eigenvalue_relative_error_max"]), _positive(dec, k)


def cell(K, variant, k):
    got = measure(K, variant, k)
    return got if isinstance(got, str) else f"{got[0]:.2e}" + ("" if got[1] else " †")


def table() -> dict:
    """Every cell of the table: ``{"<mesh>_<variant>_d<k>": error or reason}`` (``<mesh>``:
    sphere, torus, square, cube, ball), ``<...>_positive`` (⋆_k > 0) beside every error, and
    ``ball_vertices`` (TetGen's vertex count)."""
    out = {}
    for key, _, V, T, degrees in meshes():
        K = SimplicialComplex(V, T, orient="fix")
        if key == "ball":
            out["ball_vertices"] = int(len(V))
        for variant in VARIANTS:
            if variant == "intrinsic_delaunay" and K.dim == 3:  # triangle meshes only
                continue
            for k in degrees:
                got = measure(K, variant, k)
                if isinstance(got, str):
                    out[f"{key}_{variant}_d{k}"] = got
                else:
                    out[f"{key}_{variant}_d{k}"], out[f"{key}_{variant}_d{k}_positive"] = got
    return out


def _positive(dec, k):
    diagonal = dec.star_diagonal_or_none(k)
    return diagonal is None or bool(np.all(diagonal > 0))


def main() -> None:
    print("| mesh | operator | Δ0 | Δ1 | Δ2 | Δ3 |")
    print("|---|---|---|---|---|---|")
    for _, name, V, T, degrees in meshes():
        K = SimplicialComplex(V, T, orient="fix")
        for variant in VARIANTS:
            if variant == "intrinsic_delaunay" and K.dim == 3:  # triangle meshes only
                continue
            cells = [cell(K, variant, k) if k in degrees else "" for k in range(4)]
            print(f"| {name} | {variant} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
