"""Numbers of the fluid page that are no decrun run's metrics: the sources (``Source``) of
``scripts/doc_numbers.py``, each a function returning a flat dict of numbers.

They call the benchmarks' own functions (``benchmarks/bench_fluid_drift.py``,
``bench_fluid_stability.py``, ``bench_fluid_claims.py``; the steady states of
``tests/fluid_cases.py``) with the parameters the page states, so a number on the page and the
benchmark's output are one computation. All run on one BLAS thread, as the benchmarks do.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for _folder in ("tests", "benchmarks"):
    if str(ROOT / _folder) not in sys.path:
        sys.path.insert(0, str(ROOT / _folder))

#: the drift table: icosphere subdivision levels and lattice cells per side, and the schemes
#: (tests/fluid_cases.py's names) of its columns
DRIFT_LEVELS = {"rigid_rotation": (2, 3, 4, 5, 6), "degree_2": (2, 3, 4, 5, 6),
                "cellular_regular": (8, 16, 32, 64), "cellular_jittered": (8, 16, 32, 64)}
DRIFT_SCHEMES = ("thesis", "corrected", "wshd07_swept", "default")
#: the time step of the regular lattice's floor (beside the table's 1e-3)
FLOOR_DT = 2.5e-4


def drift() -> dict:
    """The steady-flow drift table: ``<case>_<level>_<scheme>`` the drift ‖w₁ − w₀‖⋆0/‖w₀‖⋆0/dt
    (1/s) of one step at ν = 0, dt = 1e-3 from an exact steady state; ``…_order`` the observed
    order log(drift ratio)/log(h ratio) against the previous level (h ∝ faces^-1/2);
    ``<case>_<level>_faces``. Also ``cellular_jittered_obtuse_min/max`` (obtuse triangles of the
    jittered lattices) and ``cellular_regular_<finest>_floor``: the default's drift there at
    dt = 2.5e-4 (its O(dt) time floor)."""
    from decrun.core.geometry import obtuse_triangle_count

    from fluid_cases import drift_per_s, steady_case

    out, obtuse = {}, []
    for case, levels in DRIFT_LEVELS.items():
        previous = None
        for level in levels:
            dec, w0, mask = steady_case(case, level)
            faces = dec.K.num_simplices(2)
            out[f"{case}_{level}_faces"] = faces
            values = {s: drift_per_s(dec, w0, mask, s) for s in DRIFT_SCHEMES}
            for s, value in values.items():
                out[f"{case}_{level}_{s}"] = value
                if previous is not None:
                    out[f"{case}_{level}_{s}_order"] = float(
                        np.log(previous[1][s] / value) / np.log(np.sqrt(faces / previous[0])))
            if case == "cellular_jittered":
                obtuse.append(int(obtuse_triangle_count(dec.K.vertices, dec.K.simplices(2))))
            if case == "cellular_regular" and level == levels[-1]:
                out[f"{case}_{level}_floor"] = drift_per_s(dec, w0, mask, "default", dt=FLOOR_DT)
            previous = (faces, values)
    out["cellular_jittered_obtuse_min"], out["cellular_jittered_obtuse_max"] = min(obtuse), max(obtuse)
    return out


#: the Fig. 7.15 channel's target face counts
CHANNEL_TARGETS = (1400, 2800, 5300, 12000)


def channel_meshes() -> dict:
    """Why ``mesh=channel`` smooths: ``raw_<target>_obtuse`` / ``raw_<target>_faces``, the obtuse
    triangles of ``triangle``'s output (``smoothing_rounds=0``) at each Fig. 7.15 target;
    ``smoothed_obtuse`` (summed over the four targets) and ``smoothed_max_angle_deg`` (their
    largest angle) after the default smoothing."""
    from decrun.core.channel_mesh import channel_mesh

    out, obtuse, angle = {}, 0, 0.0
    for target in CHANNEL_TARGETS:
        raw = channel_mesh(target_faces=target, smoothing_rounds=0)
        out[f"raw_{target}_obtuse"], out[f"raw_{target}_faces"] = int(raw.obtuse), int(raw.faces.shape[0])
        smoothed = channel_mesh(target_faces=target)
        obtuse, angle = obtuse + int(smoothed.obtuse), max(angle, float(smoothed.max_angle_deg))
    out["smoothed_obtuse"], out["smoothed_max_angle_deg"] = obtuse, angle
    return out


#: lattices of the cellular flow between walls at rest (cells per side)
WALL_CELLS = (8, 16, 32)


def cellular_walls() -> dict:
    """The cellular flow sin πx sin πy over the whole unit square (walls included), one default
    step at ν = 0, dt = 1e-3: ``<walls>_<cells>`` the drift ‖w₁ − w₀‖⋆0/‖w₀‖⋆0/dt (1/s) with
    ``slip`` and ``no_slip`` walls — the Euler condition keeps the steady state, a no-slip wall
    makes a vortex sheet."""
    from decrun.core.solvers.direct import DirectSolver
    from decrun.methods.fluid.simulation import VorticityFluid

    from fluid_cases import steady_case

    out = {}
    for cells in WALL_CELLS:
        dec, w0, _ = steady_case("cellular_regular", cells)
        out[f"faces_{cells}"] = dec.K.num_simplices(2)
        for walls in ("slip", "no_slip"):
            sim = VorticityFluid(dec, DirectSolver, dt=1e-3, viscosity=0.0, initial_vorticity=w0, walls=walls)
            w = sim.vorticity.copy()
            sim.step()
            out[f"{walls}_{cells}"] = float(np.sqrt(sim.star0 @ (sim.vorticity - w) ** 2 / (sim.star0 @ w**2)) / 1e-3)
    return out


def vortex_pair() -> dict:
    """A counter-rotating pair on the 5120-face unit sphere (Γ = 4, blob radius 0.12, 20 steps of
    0.02, ν = 0; ``bench_fluid_claims.pair_speeds``): ``centroid_<θ>`` / ``core_<θ>`` the speed
    of the +Γ vortex over Γ/(4π)·cot(θ/2), its position the centroid of the positive vorticity /
    of the core (w above half its maximum); ``lowest`` and ``highest`` of the four."""
    from bench_fluid_claims import pair_speeds

    out = {}
    for degrees in (60, 90):
        out[f"centroid_{degrees}"], out[f"core_{degrees}"] = (float(v) for v in pair_speeds(degrees, "swept_bounded"))
    out["lowest"], out["highest"] = min(out.values()), max(out.values())
    return out


def wake() -> dict:
    """The Fig. 7.15 channel after 30 steps of 0.005 (ν = 0.02, inflow 10;
    ``bench_fluid_claims.wake_asymmetry``): ``asymmetry_<target>`` = |Σ_above + Σ_below| /
    (|Σ_above| + |Σ_below|) of ⋆0w over the wake x ∈ (0.65, 1.5), ``faces_<target>``."""
    from bench_fluid_claims import wake_asymmetry

    out = {}
    for target in CHANNEL_TARGETS[:3]:
        out[f"faces_{target}"], out[f"asymmetry_{target}"] = wake_asymmetry(target, "swept_bounded")
    return out


def inviscid_channel() -> dict:
    """The Fig. 7.15 channel at ν = 0 (inflow 10, dt = 0.005; ``bench_fluid_stability.channel_run``):
    with the default (slip) walls, 200 steps at 1400 and 5300 target faces — ``slip_<target>_enstrophy``,
    ``slip_<target>_max_w`` (max |w| at the end), ``slip_<target>_faces``, ``slip_<target>_stable``,
    and ``potential_energy``: the energy ½uᵀ⋆1u of the harmonic (potential) flow the run starts
    from at 1400; with ``walls=no_slip``, 80 steps at 5300 and 12000 — ``no_slip_<target>_diverged``
    (the step the energy bound broke) and ``no_slip_<target>_faces``."""
    from bench_fluid_stability import channel_run

    from decrun.complex import SimplicialComplex
    from decrun.core.channel_mesh import channel_mesh
    from decrun.core.solvers.direct import DirectSolver
    from decrun.dec import DEC
    from decrun.methods.fluid.simulation import VorticityFluid

    out = {}
    for target in (1400, 5300):
        r = channel_run(target, "default", 200)
        out[f"slip_{target}_enstrophy"], out[f"slip_{target}_max_w"] = float(r["enstrophy"]), float(r["vorticity_max"])
        out[f"slip_{target}_faces"], out[f"slip_{target}_stable"] = r["faces"], r["diverged"] is None
    for target in (5300, 12000):
        r = channel_run(target, "no_slip", 80)
        out[f"no_slip_{target}_faces"], out[f"no_slip_{target}_diverged"] = r["faces"], r["diverged"]
    mesh = channel_mesh(target_faces=1400)
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
    sim = VorticityFluid(dec, DirectSolver, dt=0.005, viscosity=0.0, inflow_velocity=(10.0, 0.0),
                         obstacle_loops=mesh.obstacle_loops)
    out["potential_energy"] = float(sim.kinetic_energy())
    return out


#: the unforced runs at ν = 0: steps (dt = 0.02, seed 4, amplitude 5), and per mesh the schemes
#: (bench_fluid_stability.SCHEMES) run on it
UNFORCED_STEPS = 1000
UNFORCED = {"sphere_3": ("default", "swept"), "sphere_4": ("default", "swept"),
            "square_32": ("default", "no_slip", "swept_no_slip"), "square_64": ("default", "no_slip")}


def unforced() -> dict:
    """Energy ½uᵀ⋆1u and enstrophy ½Σ⋆0w² without forces at ν = 0, 1000 steps of 0.02 from a
    smooth random vorticity (``bench_fluid_stability.unforced_run``) on unit icospheres
    (``sphere_<level>``) and the unit square with walls at rest (``square_<cells>``): per
    ``<mesh>_<scheme>`` the steps that raised the energy / enstrophy above 1e-12 relative
    (``_energy_up``, ``_enstrophy_up``), the largest relative rise of one step (``_energy_rise``,
    ``_enstrophy_rise``; round-off when it is below 1e-12), the ratios at the end
    (``_energy_ratio``, ``_enstrophy_ratio``), and ``<mesh>_faces``. ``swept_no_slip`` is the
    unbounded swept rule with no-slip walls."""
    from bench_fluid_stability import SCHEMES, lattice_dec, unforced_run

    from decrun.complex import SimplicialComplex
    from decrun.dec import DEC

    from meshes_for_tests import icosphere

    SCHEMES.setdefault("swept_no_slip", ("least_squares", "swept", "no_slip"))
    out = {}
    for mesh, schemes in UNFORCED.items():
        kind, level = mesh.split("_")
        dec = DEC(SimplicialComplex(*icosphere(int(level)))) if kind == "sphere" else lattice_dec(int(level))
        out[f"{mesh}_faces"] = dec.K.num_simplices(2)
        for scheme in schemes:
            r = unforced_run(dec, scheme, UNFORCED_STEPS)
            key = f"{mesh}_{scheme}"
            out[f"{key}_steps"] = r["steps"]
            # counts as floats: held to a tolerance (a step near the 1e-12 threshold may flip)
            out[f"{key}_energy_up"], out[f"{key}_enstrophy_up"] = float(r["n_rise_e"]), float(r["n_rise_z"])
            out[f"{key}_energy_rise"], out[f"{key}_enstrophy_rise"] = float(r["max_rise_e"]), float(r["max_rise_z"])
            out[f"{key}_energy_ratio"] = float(r["energy_ratio"])
            out[f"{key}_enstrophy_ratio"] = float(r["enstrophy_ratio"])
    return out


def energy_checks() -> dict:
    """Three energy facts: ``inflow_up`` of ``inflow_steps`` — the steps that raised the energy in
    the Fig. 7.15 channel (1400 target faces, ν = 0.02, dt = 0.005; ``bench_fluid_claims.inflow_energy``,
    no bound applies with inflow), ``inflow_ratio`` its energy at the end over the start;
    ``corrected_up`` — the steps of 100 (dt = 0.01, 1280-face sphere, ν = 0) in which
    ``corrected_trapezoid`` raised a rigid rotation's enstrophy, ``corrected_rise`` the largest
    relative rise; ``trapezoid_energy_ratio`` — the energy a rigid rotation keeps after 1 s (50
    steps of 0.02) with the thesis' plain trapezoid on the same sphere."""
    from bench_fluid_claims import inflow_energy

    from decrun.complex import SimplicialComplex
    from decrun.core.solvers.direct import DirectSolver
    from decrun.dec import DEC
    from decrun.methods.fluid.initial import solid_body_rotation
    from decrun.methods.fluid.simulation import VorticityFluid

    from meshes_for_tests import icosphere

    out = {}
    _, out["inflow_steps"], up, ratio = inflow_energy(1400, 120)
    out["inflow_up"], out["inflow_ratio"] = float(up), float(ratio)  # a count held to a tolerance: a float
    dec = DEC(SimplicialComplex(*icosphere(3)))
    rotation = solid_body_rotation(dec)
    sim = VorticityFluid(dec, DirectSolver, dt=0.01, viscosity=0.0, initial_vorticity=rotation,
                         velocity="wshd07", circulation="corrected_trapezoid")
    enstrophy = [sim.diagnostics()["enstrophy"]] + [sim.step()["enstrophy"] for _ in range(100)]
    rise = np.diff(enstrophy) / np.array(enstrophy[:-1])
    out["corrected_up"], out["corrected_rise"] = float((rise > 1e-12).sum()), float(rise.max())
    sim = VorticityFluid(dec, DirectSolver, dt=0.02, viscosity=0.0, initial_vorticity=rotation,
                         velocity="wshd07", circulation="trapezoid")
    start = sim.kinetic_energy()
    for _ in range(50):
        sim.step()
    out["trapezoid_energy_ratio"] = float(sim.kinetic_energy() / start)
    return out


def enstrophy_regions(done) -> dict:
    """Where a finished channel run's enstrophy ½Σ⋆0w² is (a ``Run.derived`` of
    ``scripts/doc_numbers.py``): the fractions in the inflow strip x < 0.3
    (``enstrophy_inflow``), at the outer walls y < 0.05 or y > 0.95 (``enstrophy_walls``) and in
    the outflow strip x > 1.9 (``enstrophy_outflow``)."""
    w = np.asarray(done.result.fields["vorticity"])
    density = done.dec.star(0).diagonal() * w**2
    x, y = np.asarray(done.complex.vertices)[:, :2].T
    total = density.sum()
    return {"enstrophy_inflow": float(density[x < 0.3].sum() / total),
            "enstrophy_walls": float(density[(y < 0.05) | (y > 0.95)].sum() / total),
            "enstrophy_outflow": float(density[x > 1.9].sum() / total)}


def interval_rules() -> dict:
    """How ``app.intervals`` splits dt on the Fig. 7.15 channel (inflow 10, ν = 0.02, dt = 0.005).

    On the 1455-face channel, 10 steps against the uniform rule at ``swept_cfl = 0.25`` as the
    reference: ``deviation_per_point`` and ``deviation_uniform``, the ⋆0-weighted relative
    vorticity deviation sqrt(Σ⋆0(w − w_ref)² / Σ⋆0 w_ref²) of each rule (``faces``). On the
    12059-face channel (``big_faces``, ``big_points`` circumcenters) at the start velocities: the
    largest interval count k = max_p ceil(CFL_p / swept_cfl) (``big_k``), how many points need 3
    (``big_need_3``) and ``big_K``, the smallest 2^a or 3·2^a ≥ k the per_point rule walks."""
    from bench_fluid_channel import interval_counts

    from decrun.complex import SimplicialComplex
    from decrun.core.channel_mesh import channel_mesh
    from decrun.core.solvers.direct import DirectSolver
    from decrun.dec import DEC
    from decrun.methods.fluid.simulation import VorticityFluid

    def channel(target):
        mesh = channel_mesh(target_faces=target)
        dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
        return dec, dict(dt=0.005, viscosity=0.02, inflow_velocity=[10.0, 0.0], obstacle_loops=mesh.obstacle_loops)

    dec, common = channel(1400)
    reference = VorticityFluid(dec, DirectSolver, swept_cfl=0.25, **common)
    uniform = VorticityFluid(dec, DirectSolver, intervals="uniform", **common)
    per_point = VorticityFluid(dec, DirectSolver, intervals="per_point", **common)
    for _ in range(10):
        reference.step(), uniform.step(), per_point.step()
    star, w = reference.star0, reference.vorticity

    def deviation(sim):
        return float(np.sqrt(star @ (sim.vorticity - w) ** 2 / (star @ w**2)))

    out = {"faces": dec.K.num_simplices(2), "deviation_per_point": deviation(per_point),
           "deviation_uniform": deviation(uniform)}
    dec, common = channel(12000)
    counts = interval_counts(VorticityFluid(dec, DirectSolver, **common))
    k = int(counts.max())
    out.update(big_faces=dec.K.num_simplices(2), big_points=int(counts.size), big_k=k,
               big_need_3=int((counts == 3).sum()),
               big_K=min(n for n in (2**a * f for a in range(k.bit_length() + 1) for f in (1, 3)) if n >= k))
    return out
