"""Repair a triangle mesh with pymeshlab's cleaning filters so it builds a simplicial complex.

:func:`repair_mesh` runs, in this order (every count it changes goes into the report, so
nothing is dropped silently):

1. ``duplicate_vertices``   merge vertices with identical coordinates
   (``meshing_remove_duplicate_vertices``);
2. ``duplicate_faces``      remove faces with the same vertex set as an earlier one
   (``meshing_remove_duplicate_faces``);
3. then up to ``max_rounds`` rounds, until a round changes nothing, of

   - ``zero_area_faces``    exact zero-area faces (``meshing_remove_null_faces``);
   - ``degenerate_faces``   faces with area ≤ ``degenerate_tol`` × the mean face area — the
     same test :class:`decrun.complex.SimplicialComplex` applies (numpy);
   - ``non_manifold_edges`` faces removed so no edge lies in more than two faces
     (``meshing_repair_non_manifold_edges``, method "Remove Faces");
   - ``non_manifold_vertices`` bowtie vertices split, one copy per fan, at the same position
     (``meshing_repair_non_manifold_vertices``, ``vertdispratio=0``);
   - ``unreferenced_vertices`` vertices no face uses (``meshing_remove_unreferenced_vertices``);

4. ``reoriented``           faces flipped to make each connected component coherently
   oriented (``meshing_re_orient_faces_coherently``); a non-orientable component is
   reported (``orientable: False``) and left to the complex, which raises
   :class:`decrun.errors.NonOrientableError` for it.

Duplicate vertices are merged only before the rounds: the copies the bowtie split creates
coincide on purpose and must not be merged back.

:func:`up_axis_to_z` turns a Y-up (or X-up, or any signed axis) model so that its up axis
is +z, the axis the plots draw upwards; :data:`UP_AXIS` records which pymeshlab samples need
it (judged from renders of every sample, see the table there).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from decrun.core.geometry import triangle_areas

__all__ = ["cached_repair", "repair_mesh", "up_axis_to_z", "UP_AXIS", "ROTATION_TO_Z_UP"]

#: Up axis of each pymeshlab sample (``decrun.runner.mesh.sources.files.SAMPLE_MESHES`` names), judged by
#: rendering each sample (after :func:`repair_mesh`) with matplotlib, z drawn upwards, before
#: and after :func:`up_axis_to_z` and looking at the images:
#:
#: ================== ==== =================================================================
#: sample             up   the z-up render before the rotation / after it
#: ================== ==== =================================================================
#: bunny              y    the Stanford bunny lying down, ears along +y / sitting, ears up
#: bunny10k_textured  y    the same bunny (10k faces, open at the base) / sitting
#: cow                y    the cow standing on its tail, head up / on its four legs
#: airplane           y    nose down, wings in the x–z plane / level flight, fin up
#: colored_airplane   y    the same airplane (vertex colours) / level flight
#: bone               y    no natural up: standing on the edge of its knobs / lying flat,
#:                         thinnest extent (0.2 along y) vertical, as a bone rests
#: face               y    range scan looking up at +z / upright face looking towards −y
#: cube               z    symmetric
#: ================== ==== =================================================================
UP_AXIS: dict[str, str] = {
    "bunny": "y",
    "bunny10k_textured": "y",
    "cow": "y",
    "airplane": "y",
    "colored_airplane": "y",
    "bone": "y",
    "face": "y",
    "cube": "z",
}

#: Proper rotations (det +1) taking the named signed axis to +z; row i gives new coordinate i.
ROTATION_TO_Z_UP: dict[str, np.ndarray] = {
    "z": np.eye(3),
    "-z": np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]]),  # 180° about x
    "y": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),  # +90° about x: (x, y, z) -> (x, -z, y)
    "-y": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),  # -90° about x: (x, y, z) -> (x, z, -y)
    "x": np.array([[0.0, 1, 0], [0, 0, 1], [1, 0, 0]]),  # cyclic: (x, y, z) -> (y, z, x)
    "-x": np.array([[0.0, -1, 0], [0, 0, 1], [-1, 0, 0]]),  # (x, y, z) -> (-y, z, -x)
}


def up_axis_to_z(vertices: np.ndarray, up: str = "y") -> np.ndarray:
    """Rotate a model whose up direction is the signed axis ``up`` so that it points along +z.

    vertices (n, 3) float, model units -> (n, 3) float64, ``vertices @ R.T`` with the proper
    rotation ``R = ROTATION_TO_Z_UP[up]`` (R·e_up = e_z, det R = +1): lengths, angles and the
    orientation of every triangle (hence of the complex) are kept. ``up`` is one of
    ``x, y, z, -x, -y, -z``. Raises ``ValueError`` for another name or non-3-D vertices.
    """
    if up not in ROTATION_TO_Z_UP:
        raise ValueError(f"up axis must be one of {sorted(ROTATION_TO_Z_UP)}, got {up!r}")
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"up_axis_to_z needs (n, 3) vertices, got shape {vertices.shape}")
    return vertices @ ROTATION_TO_Z_UP[up].T


# ------------------------------------------------------------------------------------- repair
def _counts(ms) -> tuple[int, int]:
    mesh = ms.current_mesh()
    return mesh.vertex_number(), mesh.face_number()


def _arrays(ms) -> tuple[np.ndarray, np.ndarray]:
    mesh = ms.current_mesh()
    return (np.array(mesh.vertex_matrix(), dtype=np.float64),
            np.array(mesh.face_matrix(), dtype=np.int64).reshape(-1, 3))


def _meshset(vertices: np.ndarray, faces: np.ndarray):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(vertices, dtype=np.float64),
                               face_matrix=np.ascontiguousarray(faces, dtype=np.int32)))
    return ms


def _flipped_faces(before: np.ndarray, after: np.ndarray) -> int:
    """Number of rows of ``after`` that are ``before``'s row with the opposite cyclic order."""
    same = np.zeros(len(before), dtype=bool)
    for shift in range(3):
        same |= np.all(np.roll(after, shift, axis=1) == before, axis=1)
    return int((~same).sum())


def _orientable(vertices: np.ndarray, faces: np.ndarray) -> bool | None:
    """True/False by the complex's orientation test (§2.3.4); None when another defect stops it."""
    from decrun.complex import SimplicialComplex
    from decrun.errors import MeshError, NonOrientableError

    try:
        SimplicialComplex(vertices, faces, orient="fix", check_manifold=False, degenerate_tol=0.0)
    except NonOrientableError:
        return False
    except MeshError:  # another defect: the caller's own complex will name it
        return None
    return True


def repair_mesh(vertices, faces, *, max_rounds: int = 5,
                degenerate_tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Clean a triangle soup into an edge- and vertex-manifold, coherently oriented mesh.

    Parameters
    ----------
    vertices : (n, 3) or (n, 2) float, model units (2-D meshes are repaired in z = 0)
    faces : (m, 3) int, vertex indices
    max_rounds : rounds of the face/vertex repairs (each can expose work for another)
    degenerate_tol : faces with area ≤ ``degenerate_tol`` × mean face area are removed
        (the criterion of ``SimplicialComplex(degenerate_tol=...)``, default the same 1e-12)

    Returns
    -------
    vertices (n', d) float64, faces (m', 3) int64 and ``report``, a flat dict of counts:
    ``vertices_in``, ``faces_in``, ``duplicate_vertices_merged``, ``duplicate_faces_removed``,
    ``zero_area_faces_removed``, ``degenerate_faces_removed``,
    ``non_manifold_edge_faces_removed``, ``non_manifold_vertices_split`` (vertex copies
    added), ``unreferenced_vertices_removed``, ``faces_reoriented``, ``rounds``,
    ``orientable`` (bool; absent when another defect stops the orientation test),
    ``manifold`` (bool: pymeshlab finds no non-manifold edge or
    vertex at the end), ``vertices_out``, ``faces_out``. A filter that also changes the
    other count than its own (e.g. a vertex merge deleting the faces it collapses) adds
    ``<filter>_faces_removed`` / ``<filter>_vertices_removed``.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    dim = vertices.shape[1]
    if vertices.ndim != 2 or dim not in (2, 3) or faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"need (n, 2|3) vertices and (m, 3) faces, got {vertices.shape} and {faces.shape}")
    v3 = vertices if dim == 3 else np.column_stack([vertices, np.zeros(len(vertices))])
    ms = _meshset(v3, faces)
    report: dict[str, Any] = {"vertices_in": len(vertices), "faces_in": len(faces)}
    for key in ("duplicate_vertices_merged", "duplicate_faces_removed", "zero_area_faces_removed",
                "degenerate_faces_removed", "non_manifold_edge_faces_removed",
                "non_manifold_vertices_split", "unreferenced_vertices_removed"):
        report[key] = 0

    def run(name: str, apply, vertex_key: str | None, face_key: str | None, sign: int = 1) -> int:
        """Apply one filter; book its vertex/face count changes; return how much it changed."""
        nv, nf = _counts(ms)
        apply()
        nv2, nf2 = _counts(ms)
        for key, delta, what in ((vertex_key, sign * (nv - nv2), "vertices"), (face_key, nf - nf2, "faces")):
            if delta == 0:
                continue
            key = key or f"{name}_{what}_removed"
            report[key] = report.get(key, 0) + delta
        return abs(nv - nv2) + abs(nf - nf2)

    run("duplicate_vertices", ms.meshing_remove_duplicate_vertices, "duplicate_vertices_merged", None)
    run("duplicate_faces", ms.meshing_remove_duplicate_faces, None, "duplicate_faces_removed")

    def remove_degenerate():
        import pymeshlab

        v, f = _arrays(ms)
        area = triangle_areas(v, f)
        bad = area <= degenerate_tol * area.mean() if len(f) else np.zeros(0, dtype=bool)
        if bad.any():
            ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f[~bad].astype(np.int32)))

    rounds = 0
    for rounds in range(1, max_rounds + 1):  # noqa: B007 — read after the loop: the rounds it took
        changed = run("zero_area_faces", ms.meshing_remove_null_faces, None, "zero_area_faces_removed")
        changed += run("degenerate_faces", remove_degenerate, None, "degenerate_faces_removed")
        changed += run("non_manifold_edges", lambda: ms.meshing_repair_non_manifold_edges(method="Remove Faces"),
                       None, "non_manifold_edge_faces_removed")
        changed += run("non_manifold_vertices", lambda: ms.meshing_repair_non_manifold_vertices(vertdispratio=0.0),
                       "non_manifold_vertices_split", None, sign=-1)
        changed += run("unreferenced_vertices", ms.meshing_remove_unreferenced_vertices,
                       "unreferenced_vertices_removed", None)
        if changed == 0:
            break
    report["rounds"] = rounds

    before = _arrays(ms)[1]
    ms.meshing_re_orient_faces_coherently()
    v, f = _arrays(ms)
    report["faces_reoriented"] = _flipped_faces(before, f) if len(before) == len(f) else -1
    topology = ms.get_topological_measures()
    report["manifold"] = bool(topology["non_two_manifold_edges"] == 0 and topology["non_two_manifold_vertices"] == 0)
    orientable = _orientable(v, f)
    if orientable is not None:
        report["orientable"] = orientable
    report["vertices_out"], report["faces_out"] = len(v), len(f)
    return v[:, :dim].copy(), f, report


def cached_repair(vertices, faces) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """:func:`repair_mesh` (its default rounds and tolerance) through the mesh cache
    (:func:`decrun.runner.mesh.cache.cached_mesh`, keyed by the input's vertices and faces):
    the same vertices ``(n', d) float64``, faces ``(m', 3) int64`` and report, bit for bit, and
    a later run repairing the same mesh reads them back without importing pymeshlab."""
    from decrun.runner.mesh.cache import cached_mesh, content_hash

    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1] not in (2, 3) or faces.ndim != 2 or faces.shape[1] != 3:
        return repair_mesh(vertices, faces)  # its own error
    return cached_mesh("repair_mesh", {"input": content_hash(vertices, faces)}, __file__,
                       lambda: repair_mesh(vertices, faces))
