"""Structured-config schemas of decrun, registered in Hydra's ConfigStore.

Every YAML option of a config group extends its schema through its defaults list, e.g.
``conf/mesh/torus.yaml`` starts with ``defaults: [base_mesh, _self_]``. A misspelt key or
a value of the wrong type is then rejected by Hydra when the config is composed, before
any work is done.

ConfigStore nodes (group / name):

=========  ======================  ============================================
group      name                    schema
=========  ======================  ============================================
(root)     ``base_config``         :class:`DecrunConfig`
mesh       ``base_mesh``           :class:`MeshConfig` (one dataclass for all sources)
operator   ``base_operator``       :class:`OperatorConfig`
solver     ``base_solver_<name>``  :class:`DirectSolverConfig`, :class:`CGSolverConfig`,
                                   :class:`AMGSolverConfig`, :class:`PardisoSolverConfig`
app        ``base_app_<name>``     ``decrun.apps.<name>.Config`` (found automatically)
=========  ======================  ============================================

Value checks that a type cannot express (``dt > 0``, a known ``scheme``) live in the
schemas' ``__post_init__`` (raising :class:`decrun.errors.ConfigError` naming the key);
the runner instantiates every node with ``OmegaConf.to_object`` before loading the mesh.
"""

from __future__ import annotations

import importlib
import pkgutil
import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import ModuleType
from typing import Any, List, Optional

from omegaconf import MISSING

from decrun.errors import ConfigError
from decrun.core.dec import STAR_VARIANTS as _DEC_STAR_VARIANTS

# ----------------------------------------------------------------------------------
# mesh
# ----------------------------------------------------------------------------------

#: mesh sources understood by :func:`decrun.runner.meshes.load_mesh`
MESH_SOURCES = ("icosphere", "torus", "sphere_cap", "annulus", "grid", "cube", "sample", "file", "planar")


def _unit_square() -> List[List[float]]:
    return [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]


@dataclass
class MeshConfig:
    """Schema of ``cfg.mesh``: one dataclass for every source (add a field here to extend).

    ``source`` picks the generator; the other fields are read only by the source (or the
    post-processing step) they belong to. Lengths are in model units.
    """

    source: str = "icosphere"
    # icosphere (pymeshlab create_sphere: icosahedron subdivided ``subdiv`` times), sphere_cap
    subdiv: int = 3
    radius: float = 1.0
    # torus: ring radius, tube radius, segments around the ring / around the tube
    major_radius: float = 1.0
    minor_radius: float = 0.4
    major_segments: int = 32
    minor_segments: int = 16
    # sphere_cap: polar opening angle of the cap (degrees) on the unit sphere
    cap_angle_deg: float = 60.0
    # annulus (one ring of triangles; use ``refine`` for more)
    inner_radius: float = 0.5
    outer_radius: float = 1.0
    sides: int = 32
    # grid / plane: vertices per side and side lengths, centred at the origin
    nx: int = 10
    ny: int = 10
    width: float = 1.0
    height: float = 1.0
    # cube: edge length
    size: float = 1.0
    # sample: a mesh shipped inside pymeshlab (see decrun.runner.meshes.SAMPLE_MESHES)
    sample: str = "bunny10k_textured"
    # file: any format pymeshlab reads (obj, ply, off, stl, ...)
    path: str = ""
    # planar: polygon with holes (lists of [x, y]) meshed by `triangle`
    outer: List[List[float]] = field(default_factory=_unit_square)
    holes: List[List[List[float]]] = field(default_factory=list)
    min_angle_deg: float = 25.0
    max_area: float = 0.005
    # post-processing, applied in the order of ``post`` (decrun.runner.meshes.POST_STEPS);
    # each step is a no-op unless its option below enables it
    post: List[str] = field(default_factory=lambda: ["holes", "clean", "refine", "normalize", "noise"])
    clean: bool = False  # drop unreferenced vertices, keep the largest component
    refine: str = "none"  # none | loop | midpoint | isotropic
    refine_iterations: int = 1
    refine_target_edge: float = 0.0  # isotropic only; 0 = keep the mean edge length
    normalize: bool = False  # centre at the bounding-box centre, unit bounding-box diagonal
    noise: float = 0.0  # amplitude relative to the mean edge length, along vertex normals
    seed: int = 0
    # how the simplicial complex treats orientation: check (report) | fix (re-orient)
    orient: str = "check"
    # holes (decrun.runner.mesh_holes): remove the faces whose centroid lies in a ball
    # [cx, cy, cz, r] or a box [xmin, ymin, zmin, xmax, ymax, zmax] (2-D: [cx, cy, r], [xmin, ymin, xmax, ymax])
    hole_balls: List[List[float]] = field(default_factory=list)
    hole_boxes: List[List[float]] = field(default_factory=list)


# ----------------------------------------------------------------------------------
# operator
# ----------------------------------------------------------------------------------

#: Hodge-star (dual mesh) variants of decrun.core.dec.DEC
STAR_VARIANTS = set(_DEC_STAR_VARIANTS)
#: boundary adaptations; an application that implements one adds its name here at import
#: (e.g. ``BOUNDARY_ADAPTATIONS.add("flux")``) and checks ``cfg`` for the ones it supports
BOUNDARY_ADAPTATIONS = {"none"}


@dataclass
class OperatorConfig:
    """Schema of ``cfg.operator``: which DEC operator variant the application uses."""

    star: str = "circumcentric"
    boundary: str = "none"


def check_operator(cfg: Any) -> None:
    """Raise :class:`ConfigError` unless ``cfg.operator`` names known variants."""
    if cfg.star not in STAR_VARIANTS:
        raise ConfigError(f"operator.star: unknown star {cfg.star!r}; choose one of {sorted(STAR_VARIANTS)}")
    if cfg.boundary not in BOUNDARY_ADAPTATIONS:
        raise ConfigError(
            f"operator.boundary: unknown adaptation {cfg.boundary!r}; choose one of {sorted(BOUNDARY_ADAPTATIONS)}"
        )


# ----------------------------------------------------------------------------------
# solver
# ----------------------------------------------------------------------------------


@dataclass
class DirectSolverConfig:
    """scipy SuperLU (the default)."""

    name: str = "direct"
    permc_spec: str = "COLAMD"


@dataclass
class CGSolverConfig:
    """Conjugate gradients (symmetric positive definite matrices only)."""

    name: str = "cg"
    tol: float = 1e-10
    maxiter: Optional[int] = None
    preconditioner: str = "jacobi"  # jacobi | none


@dataclass
class AMGSolverConfig:
    """pyamg algebraic multigrid, used as a preconditioner of ``accel``."""

    name: str = "amg"
    tol: float = 1e-10
    maxiter: Optional[int] = None
    method: str = "smoothed_aggregation"  # smoothed_aggregation | ruge_stuben
    accel: str = "cg"  # cg | gmres | bicgstab | none


@dataclass
class PardisoSolverConfig:
    """Intel MKL PARDISO through pypardiso (the solver the thesis used)."""

    name: str = "pardiso"
    matrix_type: int = 11  # PARDISO mtype: 11 real nonsymmetric


SOLVER_SCHEMAS = {
    "direct": DirectSolverConfig,
    "cg": CGSolverConfig,
    "amg": AMGSolverConfig,
    "pardiso": PardisoSolverConfig,
}


# ----------------------------------------------------------------------------------
# root
# ----------------------------------------------------------------------------------


@dataclass
class DecrunConfig:
    """Schema of the whole composed config (``conf/config.yaml`` extends it)."""

    mesh: MeshConfig = MISSING
    operator: OperatorConfig = MISSING
    app: Any = MISSING
    solver: Any = MISSING
    #: show a tqdm progress bar over time steps (only when stderr is a terminal)
    progress: bool = True
    #: render the application's figures to PNG
    figures: bool = True


# ----------------------------------------------------------------------------------
# applications and registration
# ----------------------------------------------------------------------------------


def discover_apps() -> dict[str, ModuleType]:
    """Import every ``decrun.apps.<name>`` module that defines ``Config`` and ``run``.

    Returns ``{name: module}``. A module without both is skipped (helpers, packages).
    A module that fails to import is left out (with a warning) and recorded in
    :data:`BROKEN_APPS`, so one broken application does not break the others;
    :func:`get_app` reports its error when it is asked for.
    """
    import decrun.apps as apps_package

    found: dict[str, ModuleType] = {}
    for info in pkgutil.iter_modules(apps_package.__path__):
        if info.name.startswith("_"):
            continue
        try:
            module = importlib.import_module(f"decrun.apps.{info.name}")
        except Exception as exc:
            if info.name not in BROKEN_APPS:
                warnings.warn(f"decrun.apps.{info.name} cannot be imported and is skipped: {type(exc).__name__}: {exc}",
                              RuntimeWarning, stacklevel=2)
            BROKEN_APPS[info.name] = f"{type(exc).__name__}: {exc}"
            continue
        if hasattr(module, "Config") and callable(getattr(module, "run", None)):
            found[info.name] = module
    return found


#: application modules that failed to import: name → error message
BROKEN_APPS: dict[str, str] = {}


def get_app(name: str) -> ModuleType:
    """The application module called ``name`` (``cfg.app.name``)."""
    apps = discover_apps()
    if name in BROKEN_APPS and name not in apps:
        raise ConfigError(f"app.name: application {name!r} cannot be imported: {BROKEN_APPS[name]}")
    try:
        return apps[name]
    except KeyError:
        raise ConfigError(f"app.name: unknown application {name!r}; choose one of {sorted(apps)}") from None


_registered = False


def register_configs() -> None:
    """Store every schema in Hydra's ConfigStore (idempotent)."""
    global _registered
    if _registered:
        return
    from hydra.core.config_store import ConfigStore

    cs = ConfigStore.instance()
    cs.store(name="base_config", node=DecrunConfig)
    cs.store(group="mesh", name="base_mesh", node=MeshConfig)
    cs.store(group="operator", name="base_operator", node=OperatorConfig)
    for name, schema in SOLVER_SCHEMAS.items():
        cs.store(group="solver", name=f"base_solver_{name}", node=schema)
    for name, module in discover_apps().items():
        names = {f.name for f in fields(module.Config)}
        if "name" not in names:
            raise ConfigError(f"decrun.apps.{name}.Config needs a field `name: str = {name!r}`")
        cs.store(group="app", name=f"base_app_{name}", node=module.Config)
    _registered = True


def config_dir() -> Path:
    """Directory of the YAML configs: ``decrun/conf`` (a link to the repo's ``conf/`` in a
    checkout, a real copy inside a wheel)."""
    here = Path(__file__).resolve().parent
    for candidate in (Path(__file__).parent / "conf", here.parent / "conf"):
        if (candidate / "config.yaml").is_file():
            return candidate.resolve()
    raise ConfigError(f"cannot find the decrun configs (config.yaml) next to {here}")
