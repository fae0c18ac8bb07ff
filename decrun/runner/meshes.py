"""Mesh sources: pymeshlab primitives, pymeshlab's sample meshes, files, planar domains.

:func:`load_mesh` turns the ``cfg.mesh`` node (schema :class:`decrun.runner.config.MeshConfig`)
into a :class:`Mesh`:

1. the **source** (``cfg.source``) makes vertices and triangles
   (``SOURCES[cfg.source](cfg) -> Mesh``);
2. the **post-processing steps** listed in ``cfg.post`` run in that order
   (``POST_STEPS[name](mesh, cfg) -> Mesh``; each is a no-op unless its option enables it);
3. the result is checked (non-empty, finite, triangles, indices in range) and hashed.

To add a step: write ``def my_step(mesh: Mesh, cfg) -> Mesh``, register it in
:data:`POST_STEPS`, add its option fields to ``MeshConfig`` and its name to the default
``MeshConfig.post`` list. Deeper checks (manifold, orientation, degenerate triangles) are
done by :class:`decrun.core.complex.SimplicialComplex`; a bad mesh is reported, never silently
repaired (``clean`` is off by default).

``Mesh.meta`` carries what the source knows and the complex does not, for the
applications (the runner hands it over as ``complex.meta``):

- ``source``, ``label`` (short human name), ``path`` (file/sample), ``steps`` (applied)
- ``hash``: sha256 of vertices and triangles (:func:`mesh_hash`)
- ``mean_edge_length``: of the final mesh
- ``clean_vertices``: ``(n0, d)`` positions before ``noise`` was added (only when noise > 0)
- ``noise_amplitude``: the absolute noise standard deviation (``noise * mean edge length``)
- ``dropped_vertices`` / ``dropped_faces``: what ``clean`` removed (only when clean ran)
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from decrun.errors import ConfigError, MeshError
from decrun.runner.mesh_holes import holes_step

# ----------------------------------------------------------------------------------
# the mesh record
# ----------------------------------------------------------------------------------


@dataclass
class Mesh:
    """Vertices ``(n0, d) float64`` (d = 2 or 3), triangles ``(n2, 3) int64``, metadata."""

    vertices: np.ndarray
    simplices: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def faces(self) -> np.ndarray:
        """Alias of ``simplices`` for triangle meshes."""
        return self.simplices


def mesh_hash(vertices: np.ndarray, simplices: np.ndarray) -> str:
    """sha256 hex digest of the shapes, the little-endian float64 vertices and int64 simplices."""
    h = hashlib.sha256()
    v = np.ascontiguousarray(vertices, dtype="<f8")
    s = np.ascontiguousarray(simplices, dtype="<i8")
    h.update(repr((v.shape, s.shape)).encode())
    h.update(v.tobytes())
    h.update(s.tobytes())
    return h.hexdigest()


def mean_edge_length(vertices: np.ndarray, simplices: np.ndarray) -> float:
    """Mean length of the distinct edges of the triangles (model units)."""
    edges = np.concatenate([simplices[:, [0, 1]], simplices[:, [1, 2]], simplices[:, [2, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    return float(np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1).mean())


def vertex_normals(vertices: np.ndarray, simplices: np.ndarray) -> np.ndarray:
    """Unit vertex normals ``(n0, 3)``: area-weighted sum of the incident triangles' normals.

    Vertices whose weighted sum vanishes get the zero vector.
    """
    p0, p1, p2 = (vertices[simplices[:, i]] for i in range(3))
    face_normal = np.cross(p1 - p0, p2 - p0)  # length = 2 * area
    n0, m = len(vertices), len(simplices)
    incidence = sp.csr_matrix(
        (np.ones(3 * m), (simplices.ravel(), np.repeat(np.arange(m), 3))), shape=(n0, m)
    )
    normals = incidence @ face_normal
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)


# ----------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------


def _get(cfg: Any, key: str):
    return cfg[key] if isinstance(cfg, dict) else getattr(cfg, key)


def _require(condition: bool, key: str, message: str) -> None:
    if not condition:
        raise ConfigError(f"mesh.{key}: {message}")


def _from_meshset(ms, what: str) -> tuple[np.ndarray, np.ndarray]:
    mesh = ms.current_mesh()
    vertices = np.array(mesh.vertex_matrix(), dtype=np.float64)
    faces = np.array(mesh.face_matrix(), dtype=np.int64).reshape(-1, 3)
    if faces.shape[0] == 0:
        raise MeshError(f"{what}: the mesh has no faces ({len(vertices)} vertices)")
    return vertices, faces


def _meshset(vertices: np.ndarray, simplices: np.ndarray):
    import pymeshlab

    v3 = vertices if vertices.shape[1] == 3 else np.column_stack([vertices, np.zeros(len(vertices))])
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(v3), face_matrix=np.ascontiguousarray(simplices, dtype=np.int32)))
    return ms


def _primitive(filter_name: str, label: str, **params) -> Mesh:
    import pymeshlab

    ms = pymeshlab.MeshSet()
    getattr(ms, filter_name)(**params)
    vertices, faces = _from_meshset(ms, f"mesh.source={label}")
    return Mesh(vertices, faces, {"source": label, "label": label})


# ----------------------------------------------------------------------------------
# sources
# ----------------------------------------------------------------------------------


def icosphere(cfg) -> Mesh:
    """Icosahedron subdivided ``subdiv`` times, projected to the sphere of ``radius``
    (10·4^subdiv + 2 vertices)."""
    _require(0 <= cfg.subdiv <= 8, "subdiv", f"must be in 0..8, got {cfg.subdiv}")
    _require(cfg.radius > 0, "radius", f"must be > 0, got {cfg.radius}")
    mesh = _primitive("create_sphere", "icosphere", radius=float(cfg.radius), subdiv=int(cfg.subdiv))
    mesh.meta["label"] = f"icosphere{cfg.subdiv}"
    return mesh


def torus(cfg) -> Mesh:
    """Torus with ring radius ``major_radius`` and tube radius ``minor_radius``."""
    _require(cfg.major_radius > cfg.minor_radius > 0, "minor_radius", "need major_radius > minor_radius > 0")
    _require(cfg.major_segments >= 3 and cfg.minor_segments >= 3, "major_segments", "need >= 3 segments each way")
    return _primitive(
        "create_torus", "torus",
        hradius=float(cfg.major_radius), vradius=float(cfg.minor_radius),
        hsubdiv=int(cfg.major_segments), vsubdiv=int(cfg.minor_segments),
    )


def sphere_cap(cfg) -> Mesh:
    """Cap of the unit sphere with polar opening angle ``cap_angle_deg`` (a disk)."""
    _require(0 < cfg.cap_angle_deg < 180, "cap_angle_deg", f"must be in (0, 180), got {cfg.cap_angle_deg}")
    _require(0 <= cfg.subdiv <= 8, "subdiv", f"must be in 0..8, got {cfg.subdiv}")
    return _primitive("create_sphere_cap", "sphere_cap", angle=float(cfg.cap_angle_deg), subdiv=int(cfg.subdiv))


def annulus(cfg) -> Mesh:
    """Planar ring (z = 0) between ``inner_radius`` and ``outer_radius``, ``sides`` sides."""
    _require(cfg.outer_radius > cfg.inner_radius > 0, "inner_radius", "need outer_radius > inner_radius > 0")
    _require(cfg.sides >= 3, "sides", f"must be >= 3, got {cfg.sides}")
    return _primitive(
        "create_annulus", "annulus",
        internalradius=float(cfg.inner_radius), externalradius=float(cfg.outer_radius), sides=int(cfg.sides),
    )


def grid(cfg) -> Mesh:
    """Triangulated ``nx`` × ``ny`` vertex grid of ``width`` × ``height`` in z = 0, centred."""
    _require(cfg.nx >= 2 and cfg.ny >= 2, "nx", f"need nx, ny >= 2, got {cfg.nx}, {cfg.ny}")
    _require(cfg.width > 0 and cfg.height > 0, "width", "need width, height > 0")
    mesh = _primitive(
        "create_grid", "grid",
        numvertx=int(cfg.nx), numverty=int(cfg.ny),
        absscalex=float(cfg.width), absscaley=float(cfg.height), center=True,
    )
    return mesh


def cube(cfg) -> Mesh:
    """Cube of edge ``size`` centred at the origin (8 vertices, 12 triangles)."""
    _require(cfg.size > 0, "size", f"must be > 0, got {cfg.size}")
    return _primitive("create_cube", "cube", size=float(cfg.size))


def sample_mesh_dir() -> Path:
    """Directory of the sample meshes shipped inside the installed pymeshlab package."""
    import pymeshlab

    return Path(pymeshlab.__file__).resolve().parent / "tests" / "sample_meshes"


#: ``mesh.sample`` names → files under :func:`sample_mesh_dir`
SAMPLE_MESHES = {
    "bunny": "bunny.obj",
    "bunny10k_textured": "bunny10k_textured.obj",
    "cow": "cow.obj",
    "airplane": "airplane.obj",
    "colored_airplane": "colored_airplane.ply",
    "bone": "bone.ply",
    "face": "rangemaps/face000.ply",
    "cube": "cube.obj",
}


def _read_file(path: Path, key: str, label: str) -> Mesh:
    import pymeshlab

    if not path.exists():
        raise MeshError(f"{key}={str(path)!r}: file not found")
    if not path.is_file():
        raise MeshError(f"{key}={str(path)!r}: not a file")
    if path.stat().st_size == 0:
        raise MeshError(f"{key}={str(path)!r}: the file is empty")
    ms = pymeshlab.MeshSet()
    try:
        ms.load_new_mesh(str(path))
    except Exception as exc:  # pymeshlab.PyMeshLabException and friends
        raise MeshError(f"{key}={str(path)!r}: pymeshlab cannot read it: {str(exc).strip()}") from exc
    vertices, faces = _from_meshset(ms, f"{key}={str(path)!r}")
    return Mesh(vertices, faces, {"source": label, "label": path.stem, "path": str(path)})


def sample(cfg) -> Mesh:
    """A mesh shipped with pymeshlab, by name (see :data:`SAMPLE_MESHES`)."""
    _require(cfg.sample in SAMPLE_MESHES, "sample", f"unknown sample {cfg.sample!r}; choose one of {sorted(SAMPLE_MESHES)}")
    mesh = _read_file(sample_mesh_dir() / SAMPLE_MESHES[cfg.sample], "mesh.sample", "sample")
    mesh.meta["label"] = cfg.sample
    return mesh


def from_file(cfg) -> Mesh:
    """Any triangle mesh pymeshlab reads (obj, ply, off, stl, ...), by ``path``."""
    _require(bool(cfg.path), "path", "is empty; give the mesh file, e.g. mesh.path=/data/dragon.ply")
    return _read_file(Path(str(cfg.path)).expanduser(), "mesh.path", "file")


def _polygon(points, key: str) -> np.ndarray:
    poly = np.asarray(points, dtype=np.float64)
    _require(poly.ndim == 2 and poly.shape[1] == 2 and len(poly) >= 3, key, "a polygon needs >= 3 points [x, y]")
    _require(bool(np.isfinite(poly).all()), key, "non-finite coordinate")
    x, y = poly[:, 0], poly[:, 1]
    signed_area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    _require(abs(signed_area) > 0, key, "the polygon has zero area")
    return poly


def _ring_segments(start: int, count: int) -> np.ndarray:
    idx = np.arange(start, start + count)
    return np.column_stack([idx, np.roll(idx, -1)])


def _point_inside(poly: np.ndarray) -> np.ndarray:
    """A point strictly inside a simple polygon: centroid of one triangle of its triangulation."""
    import triangle

    t = triangle.triangulate({"vertices": poly, "segments": _ring_segments(0, len(poly))}, "p")
    return t["vertices"][t["triangles"][0]].mean(axis=0)


def planar(cfg) -> Mesh:
    """Polygon ``outer`` minus polygons ``holes`` (2-D vertices), meshed by ``triangle`` with
    minimum angle ``min_angle_deg`` and maximum triangle area ``max_area`` (Shewchuk's
    quality switches ``pq<angle>a<area>``)."""
    import triangle

    outer = _polygon(cfg.outer, "outer")
    holes = [_polygon(h, f"holes[{i}]") for i, h in enumerate(cfg.holes)]
    _require(0 < cfg.min_angle_deg <= 34, "min_angle_deg", f"must be in (0, 34] (triangle's guarantee), got {cfg.min_angle_deg}")
    _require(cfg.max_area > 0, "max_area", f"must be > 0, got {cfg.max_area}")
    rings = [outer, *holes]
    starts = np.cumsum([0] + [len(r) for r in rings[:-1]])
    domain = {
        "vertices": np.concatenate(rings),
        "segments": np.concatenate([_ring_segments(s, len(r)) for s, r in zip(starts, rings)]),
    }
    if holes:
        domain["holes"] = np.array([_point_inside(h) for h in holes])
    t = triangle.triangulate(domain, f"pq{float(cfg.min_angle_deg)}a{float(cfg.max_area)}")
    vertices = np.asarray(t["vertices"], dtype=np.float64)
    faces = np.asarray(t["triangles"], dtype=np.int64)
    if len(faces) == 0:
        raise MeshError("mesh.source=planar: triangle produced no triangles")
    # triangle lists the input points first; drop any it left unused (e.g. inside holes)
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    if not used.all():
        remap = np.cumsum(used) - 1
        vertices, faces = vertices[used], remap[faces]
    return Mesh(vertices, faces, {"source": "planar", "label": f"planar{len(holes)}h"})


#: ``mesh.source`` → generator ``(cfg) -> Mesh``
SOURCES: dict[str, Callable[[Any], Mesh]] = {
    "icosphere": icosphere,
    "torus": torus,
    "sphere_cap": sphere_cap,
    "annulus": annulus,
    "grid": grid,
    "plane": grid,
    "cube": cube,
    "sample": sample,
    "file": from_file,
    "planar": planar,
}

# ----------------------------------------------------------------------------------
# post-processing steps
# ----------------------------------------------------------------------------------


def clean_step(mesh: Mesh, cfg) -> Mesh:
    """``clean``: keep the largest connected component (by triangle count, components
    joined through shared vertices) and drop unreferenced vertices."""
    if not cfg.clean:
        return mesh
    V, F = mesh.vertices, mesh.simplices
    m = len(F)
    incidence = sp.csr_matrix((np.ones(3 * m), (np.repeat(np.arange(m), 3), F.ravel())), shape=(m, len(V)))
    _, label = connected_components(incidence @ incidence.T, directed=False)
    keep_faces = label == np.argmax(np.bincount(label))
    F = F[keep_faces]
    used = np.zeros(len(V), dtype=bool)
    used[F.ravel()] = True
    remap = np.cumsum(used) - 1
    meta = dict(mesh.meta, dropped_vertices=int((~used).sum()), dropped_faces=int((~keep_faces).sum()))
    if "clean_vertices" in meta:
        meta["clean_vertices"] = meta["clean_vertices"][used]
    return Mesh(V[used], remap[F], meta)


def refine_step(mesh: Mesh, cfg) -> Mesh:
    """``refine``: ``loop`` / ``midpoint`` subdivision or ``isotropic`` remeshing (pymeshlab),
    ``refine_iterations`` times. Drops ``clean_vertices`` (the connectivity changed)."""
    import pymeshlab

    if cfg.refine == "none":
        return mesh
    _require(cfg.refine in ("loop", "midpoint", "isotropic"), "refine", f"unknown {cfg.refine!r}; choose none|loop|midpoint|isotropic")
    _require(1 <= cfg.refine_iterations <= 10, "refine_iterations", f"must be in 1..10, got {cfg.refine_iterations}")
    dim = mesh.vertices.shape[1]
    ms = _meshset(mesh.vertices, mesh.simplices)
    if cfg.refine == "loop":
        ms.meshing_surface_subdivision_loop(iterations=int(cfg.refine_iterations), threshold=pymeshlab.PercentageValue(0.0))
    elif cfg.refine == "midpoint":
        ms.meshing_surface_subdivision_midpoint(iterations=int(cfg.refine_iterations), threshold=pymeshlab.PercentageValue(0.0))
    else:
        _require(cfg.refine_target_edge >= 0, "refine_target_edge", "must be >= 0")
        target = cfg.refine_target_edge or mean_edge_length(mesh.vertices, mesh.simplices)
        ms.meshing_isotropic_explicit_remeshing(iterations=int(cfg.refine_iterations), targetlen=pymeshlab.PureValue(float(target)))
    vertices, faces = _from_meshset(ms, f"mesh.refine={cfg.refine}")
    meta = {k: v for k, v in mesh.meta.items() if k != "clean_vertices"}
    return Mesh(vertices[:, :dim], faces, meta)


def normalize_step(mesh: Mesh, cfg) -> Mesh:
    """``normalize``: translate the bounding-box centre to the origin, scale to unit diagonal."""
    if not cfg.normalize:
        return mesh
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    center, diagonal = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    if diagonal == 0:
        raise MeshError("mesh.normalize: all vertices coincide")
    meta = dict(mesh.meta)
    if "clean_vertices" in meta:
        meta["clean_vertices"] = (meta["clean_vertices"] - center) / diagonal
    return Mesh((mesh.vertices - center) / diagonal, mesh.simplices, meta)


def noise_step(mesh: Mesh, cfg) -> Mesh:
    """``noise``: displace every vertex by ``noise · h · ξ_i`` along its unit normal, where
    ``h`` is the mean edge length and ``ξ_i ~ N(0, 1)`` (generator seeded by ``seed``).
    For planar (2-D) meshes, which have no normal, the direction is a random in-plane unit
    vector. Keeps the noise-free positions in ``meta['clean_vertices']``."""
    _require(cfg.noise >= 0, "noise", f"must be >= 0, got {cfg.noise}")
    if cfg.noise == 0:
        return mesh
    rng = np.random.default_rng(int(cfg.seed))
    V, F = mesh.vertices, mesh.simplices
    h = mean_edge_length(V, F)
    if V.shape[1] == 3:
        direction = vertex_normals(V, F)
    else:
        angle = rng.uniform(0, 2 * np.pi, len(V))
        direction = np.column_stack([np.cos(angle), np.sin(angle)])
    amplitude = float(cfg.noise) * h
    displaced = V + amplitude * rng.standard_normal(len(V))[:, None] * direction
    meta = dict(mesh.meta, clean_vertices=V.copy(), noise_amplitude=amplitude)
    return Mesh(displaced, F, meta)


#: ``mesh.post`` names → step ``(mesh, cfg) -> mesh`` (no-op unless its option is set)
POST_STEPS: dict[str, Callable[[Mesh, Any], Mesh]] = {
    "clean": clean_step,
    "refine": refine_step,
    "normalize": normalize_step,
    "noise": noise_step,
    "holes": holes_step,  # decrun.runner.mesh_holes: cut balls/boxes out (hole_balls, hole_boxes)
}


# ----------------------------------------------------------------------------------
# entry point
# ----------------------------------------------------------------------------------


def check_mesh(mesh: Mesh, what: str = "mesh") -> None:
    """Basic checks every source must pass; raises :class:`MeshError` naming the culprit."""
    V, F = mesh.vertices, mesh.simplices
    if V.ndim != 2 or V.shape[1] not in (2, 3) or len(V) == 0:
        raise MeshError(f"{what}: vertices must be a non-empty (n, 2|3) array, got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise MeshError(f"{what}: need a non-empty (m, 3) triangle array, got shape {F.shape}")
    bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
    if len(bad):
        raise MeshError(f"{what}: vertex {int(bad[0])} has a non-finite coordinate {V[bad[0]].tolist()} ({len(bad)} such vertices)")
    out = np.flatnonzero(((F < 0) | (F >= len(V))).any(axis=1))
    if len(out):
        raise MeshError(f"{what}: face {int(out[0])} {F[out[0]].tolist()} references a vertex outside [0, {len(V)})")


def load_mesh(cfg) -> Mesh:
    """Build the mesh described by ``cfg`` (the ``cfg.mesh`` node; DictConfig, MeshConfig or
    any object with those attributes).

    Returns a :class:`Mesh` with ``vertices (n0, 3)`` (``(n0, 2)`` for ``planar``),
    ``simplices (n2, 3) int64`` and ``meta`` (see the module docstring).
    Raises :class:`ConfigError` for a bad option, :class:`MeshError` for a bad mesh.
    """
    source = _get(cfg, "source")
    if source not in SOURCES:
        raise ConfigError(f"mesh.source: unknown source {source!r}; choose one of {sorted(SOURCES)}")
    for step in _get(cfg, "post"):
        if step not in POST_STEPS:
            raise ConfigError(f"mesh.post: unknown step {step!r}; choose from {sorted(POST_STEPS)}")
    if _get(cfg, "orient") not in ("check", "fix"):
        raise ConfigError(f"mesh.orient: must be check or fix, got {_get(cfg, 'orient')!r}")
    mesh = SOURCES[source](cfg)
    mesh = replace(mesh, simplices=np.asarray(mesh.simplices, dtype=np.int64), vertices=np.asarray(mesh.vertices, dtype=np.float64))
    label = mesh.meta.get("label", source)
    check_mesh(mesh, f"mesh {label}")
    applied = []
    for step in _get(cfg, "post"):
        before = mesh
        mesh = POST_STEPS[step](mesh, cfg)
        if mesh is not before:
            applied.append(step)
    check_mesh(mesh, f"mesh {label} after {applied}")
    mesh.meta.setdefault("source", source)
    mesh.meta["steps"] = applied
    mesh.meta["mean_edge_length"] = mean_edge_length(mesh.vertices, mesh.simplices)
    mesh.meta["hash"] = mesh_hash(mesh.vertices, mesh.simplices)
    return mesh
