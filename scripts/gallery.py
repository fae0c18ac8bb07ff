"""Regenerate the gallery: one figure (or a pair to compare) per thesis-figure experiment
(conf/experiment/fig*.yaml) and per model experiment that has one (darcy_convergence), and one per
shipped declarative model (conf/app/<model>.yaml).

    python scripts/gallery.py [--out docs] [--only fig5_8_t_hole model_halfar ...]

Each entry runs single runs of ``+experiment=<name>`` (a model entry: its own overrides) through
the same composition as ``decrun``, copies the named figure to ``<out>/gallery/<name>__<n>.png``
and writes ``<out>/gallery.md`` with the images, the command and the numbers under each — the
run's metrics, and for a model entry the numbers derived from its fields (Klausmeier's band
spacing) — as placeholders the docs build fills from ``docs/numbers.json`` (``scripts/doc_numbers.py``
runs the same runs, derived numbers included; ``tests/test_numbers.py`` checks them), so none is
typed and none is older than the code. The page holds no number of its own: it is written whole
from the tables below every time; ``--only`` reruns the named sections' figures and leaves the
others' images as they are. Takes a few minutes on two cores.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

#: experiment → (caption, [(overrides, figure stem, metrics shown), ...])
GALLERY = {
    "fig1_2_smoothing": ("Fig. 1.2 — the noisy scanned bunny smoothed by mean curvature flow at 2× the explicit "
                         "critical step: implicit Euler smooths, explicit Euler blows up (shared axes).", [
        (["app.scheme=implicit", "app.dt_factor=2.0"], "smoothing",
         ["stable", "distance_to_clean_rms_initial", "distance_to_clean_rms", "volume_drift_rel"]),
        (["app.scheme=explicit", "app.dt_factor=2.0"], "smoothing", ["stable", "diverged_at_step"]),
    ]),
    "fig5_5_flat_hole": ("Fig. 5.5 — a flat mesh with a hole: the conformal border is exact with the default "
                         "Cauchy–Riemann rows at reflex border vertices, not with the thesis' harmonic rows.", [
        ([], "uv_layout", ["angle_distortion_mean_deg", "is_embedding"]),
        (["app.reflex_rows=harmonic"], "uv_layout", ["angle_distortion_mean_deg", "is_embedding"]),
    ]),
    "fig5_6_open_patch": ("Fig. 5.6 — a nearly flat patch cut straight along a plane (holes split along the "
                          "box surface): conformal border, both reflex-row rules.", [
        ([], "checkerboard", ["angle_distortion_mean_deg", "is_embedding"]),
        (["app.reflex_rows=harmonic"], "uv_layout", ["angle_distortion_mean_deg", "is_embedding"]),
    ]),
    "fig5_7_half_sphere_holes": ("Fig. 5.7 — a half sphere with eyes, a smile and ears cut along the balls' "
                                 "spheres; several borders (§5.2.3).", [
        ([], "uv_layout", ["angle_distortion_mean_deg", "border_loops", "is_embedding"]),
        (["app.reflex_rows=harmonic"], "uv_layout", ["angle_distortion_mean_deg", "is_embedding"]),
    ]),
    "fig5_8_t_hole": ("Fig. 5.8 — a sphere with a T-shaped hole: the conformal border fails (not an "
                      "embedding), the free border does not.", [
        ([], "uv_layout", ["angle_distortion_mean_deg", "flipped_triangles", "is_embedding"]),
        (["app.border=free"], "uv_layout", ["angle_distortion_mean_deg", "flipped_triangles", "is_embedding"]),
    ]),
    "fig6_7_cube": ("Fig. 6.7 — source and sink on the front of a cube, a stroke on the back: `fixed` "
                    "magnitude changes the front, `precomputed` barely.", [
        (["app.stroke_magnitude=fixed", "app.stroke_length=5.0"], "field", ["field_change_region_relative"]),
        (["app.stroke_magnitude=precomputed"], "field", ["field_change_region_relative"]),
    ]),
    "fig6_8_vortex": ("Fig. 6.8 (a) — a closed stroke around the clean sphere: two +1 singularities "
                      "(clusters of neighbouring discrete singularities merged).", [
        ([], "field", ["singularities", "singularity_cluster_indices", "index_sum"]),
    ]),
    "fig6_8_saddle": ("Fig. 6.8 (b) — four strokes make a saddle at the north pole.", [
        ([], "field", ["singularities", "singularity_cluster_indices", "index_sum"]),
    ]),
    "fig6_8_spiral": ("Fig. 6.8 (c) — source and sink with a spiralling stroke.", [
        ([], "field", ["singularities", "singularity_cluster_indices", "index_sum"]),
    ]),
    "fig6_9_square": ("Fig. 6.9 — a source and a stroke in a square: `boundary=none` keeps the field "
                      "tangential to the border, `flux` lets it cross. With `flux` the constant fields are "
                      "in the kernel and the minimum-norm solution is taken (see the vector field page): without the stroke it "
                      "shows two saddles; with it a saddle next to the source (a cluster of index 0, left "
                      "unmarked).", [
        (["boundary=none"], "field", ["border_normal_flux_mean", "adjointness_defect"]),
        (["boundary=flux"], "field", ["border_normal_flux_mean", "adjointness_defect"]),
        (["boundary=flux", "app.strokes=[]"], "field", ["singularity_cluster_indices", "border_normal_flux_mean"]),
    ]),
    "fig7_1_stirred_sphere": ("Fig. 7.1 / 7.18 — a viscous fluid on a clean icosphere (1280 triangles, none "
                              "obtuse), stirred by a stroke for half a second: vorticity over time.", [
        ([], "vorticity", ["stable", "max_abs_divergence", "circulation_drift"]),
    ]),
    "fig7_14_one_obstacle": ("Fig. 7.14 — flow past one obstacle in a channel meshed without obtuse triangles "
                             "(~1400 faces), inflow from the left: the obstacle sheds vorticity of both signs.", [
        ([], "vorticity", ["stable", "max_abs_divergence", "obtuse_triangles", "n_faces"]),
    ]),
    "fig7_15_density_and_time_step": ("Fig. 7.15 — the same flow (inflow 10 units/s, ν = 0.02) on 1400 and 2800 "
                                      "target faces: the wake of the obstacle at t = 0.6 s.", [
        (["mesh.target_faces=1400"], "vorticity", ["stable", "enstrophy_final", "n_faces"]),
        (["mesh.target_faces=2800"], "vorticity", ["stable", "enstrophy_final", "n_faces"]),
    ]),
    "fig7_17_viscosity": ("Fig. 7.17 — the channel flow at 2800 faces without and with viscosity.", [
        (["app.viscosity=0.0"], "vorticity", ["stable", "enstrophy_final"]),
        (["app.viscosity=0.08"], "vorticity", ["stable", "enstrophy_final"]),
    ]),
    "darcy_convergence": ("Darcy flow in mixed form with Whitney forms (`app=darcy`): the pressure "
                          "p = sin(πx) sin(πy) + x z in colour and the velocity u = −∇p (the Raviart–Thomas field "
                          "of the discrete fluxes) as arrows, on the square and inside the tetrahedral box.", [
        (["mesh=darcy/square_2"], "flow", ["pressure_l2_error_rel", "flux_l2_error_rel", "divergence_residual"]),
        (["mesh=darcy/box_2"], "flow", ["pressure_l2_error_rel", "flux_l2_error_rel", "divergence_residual"]),
    ]),
}


def _bands(done):
    """(xs, profile, peaks, inside): n averaged across the strip (over y, per x), the indices of
    its peaks above 3 between the absorbing layers, and that region (|x| < L/2 − 60)."""
    import numpy as np

    vertices, n = done.complex.vertices, np.asarray(done.result.fields["n"])
    xs, inverse = np.unique(np.round(vertices[:, 0], 9), return_inverse=True)
    profile = np.bincount(inverse, weights=n) / np.bincount(inverse)
    inside = np.abs(xs) < 0.5 * done.experiment.app.constants["L"] - 60
    peaks = [i for i in range(1, len(xs) - 1) if inside[i] and profile[i] > 3
             and profile[i] >= profile[i - 1] and profile[i] > profile[i + 1]]
    return xs, profile, peaks, inside


def band_profile(done, target: Path) -> None:
    """Klausmeier's bands as a profile — the strip is 25 times longer than wide, too thin to
    read as a picture: n averaged across the slope against x, its counted peaks marked, the
    absorbing layers shaded."""
    from decrun.runner.plots.common import new_figure

    xs, profile, peaks, inside = _bands(done)
    fig = new_figure(8.0, 3.0)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(xs, profile, lw=1.0, label="n averaged across the slope")
    ax.plot(xs[peaks], profile[peaks], "o", ms=4, label=f"the {len(peaks)} peaks counted")
    for side in (-1, 1):
        edge = side * xs[inside].max()
        ax.axvspan(edge, side * abs(xs).max(), color="0.85", lw=0)
    ax.set_xlabel("x (water flows towards −x; grey: absorbing layers, not counted)")
    ax.set_ylabel("n (biomass)")
    ax.set_xlim(xs.min(), xs.max())
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    fig.savefig(target, dpi=110, bbox_inches="tight")


def band_spacing(done) -> dict:
    """Klausmeier's bands: the mean spacing of the peaks of :func:`_bands`, and 2π/k_max of the
    linear dispersion relation (the largest Re λ(k) of [[−1 − n*² + iνk, −2m], [n*², m − k²]])."""
    import numpy as np

    xs, profile, peaks, inside = _bands(done)
    c = done.experiment.app.constants
    ns = (c["a"] + np.sqrt(c["a"] ** 2 - 4 * c["m"] ** 2)) / (2 * c["m"])
    k = np.linspace(0.01, 1.0, 20000)
    rate = [np.linalg.eigvals(np.array([[-1 - ns ** 2 + 1j * c["nu"] * q, -2 * c["m"]], [ns ** 2, c["m"] - q * q]]))
            .real.max() for q in k]
    spacing = (xs[peaks[-1]] - xs[peaks[0]]) / (len(peaks) - 1) if len(peaks) > 1 else float("nan")
    return {"bands": len(peaks), "band_spacing": spacing, "fastest_growing_wavelength": 2 * np.pi / k[int(np.argmax(rate))]}


#: model section → (caption, [(overrides, figure stem or a drawing function, numbers shown, derived numbers
#: or None), ...]);
#: each a single run of ``decrun <overrides>`` (``app.animation=false`` added: no GIF)
MODELS = {
    "model_heat": ("`app=heat` — the l = 2 harmonic x·y on the unit sphere decays as e^(−6t) "
                   "(Crank–Nicolson); the error is against that exact solution.", [
        (["+experiment=heat_sphere"], "u_snapshots", ["l2_error_rel", "mass", "n_vertices"], None),
    ]),
    "model_poisson": ("`app=poisson` — Δu = f on the unit square with the exact solution's border values.", [
        (["app=poisson"], "u", ["l2_error_rel", "max_abs_error", "n_vertices"], None),
    ]),
    "model_newton_cooling": ("`app=newton_cooling` — a square plate cooling to the air through a Robin border "
                             "(∂u/∂n + αu = αu_air); the error is against the slowest mode, exact when μ tan(μ/2) = α.", [
        (["app=newton_cooling"], "u", ["l2_error_rel", "mean_temperature", "n_vertices"], None),
    ]),
    "model_wave": ("`app=wave` — the l = 2 mode through one period 2π/√6 (Störmer–Verlet): `projection` "
                   "is its amplitude, back to 1, the modified energy conserved.", [
        (["app=wave", "app.t_end=2.565"], "u_snapshots", ["projection", "energy_modified", "n_vertices"], None),
    ]),
    "model_heat_geodesics": ("`app=heat_geodesics` — geodesic distance on the unit sphere by the heat method, "
                             "against the great-circle distance; the source (vertex 2199) faces the viewer.", [
        (["+experiment=heat_geodesics_sphere", "mesh.subdiv=4", "app.constants.source=2199"], "distance",
         ["mean_relative_error", "max_abs_error", "n_faces"], None),
    ]),
    "model_mcf": ("`app=mcf` — mean curvature flow of the noisy icosphere (implicit Euler): the Dirichlet "
                  "energy of the coordinates over time.", [
        (["app=mcf", "app.steps=40"], "metrics", ["dirichlet_energy", "n_vertices"], None),
    ]),
    "model_gray_scott_square": ("`+experiment=gray_scott_pearson` — Gray–Scott on Pearson's square: spots at "
                                "(F, k) = (0.035, 0.065), stripes at (0.04, 0.06). `pattern` is 1 when "
                                "v_std (the ⋆0-weighted standard deviation of v) exceeds 0.02.", [
        (["+experiment=gray_scott_pearson"], "v_snapshots", ["v_std", "pattern"], None),
        (["+experiment=gray_scott_pearson", "app.constants.F=0.04", "app.constants.k=0.06"], "v_snapshots",
         ["v_std", "pattern"], None),
    ]),
    "model_gray_scott_sphere": ("`+experiment=gray_scott_sphere` — the same two regimes on the unit sphere "
                                "(seeded at the six poles of the axes).", [
        (["+experiment=gray_scott_sphere"], "v_snapshots", ["v_std", "pattern"], None),
        (["+experiment=gray_scott_sphere", "app.constants.F=0.04", "app.constants.k=0.06"], "v_snapshots",
         ["v_std", "pattern"], None),
    ]),
    "model_brusselator": ("`app=brusselator` — beyond the Hopf point B = 1 + A² the homogeneous state "
                          "oscillates (B = 2.5, left; growth to the limit cycle), below it decays (B = 1.5, right).", [
        (["app=brusselator"], "metrics", ["growth_rate_linear", "deviation_rms"], None),
        (["app=brusselator", "app.constants.B=1.5"], "metrics",
         ["growth_rate_linear", "growth_rate_measured", "deviation_rms"], None),
    ]),
    "model_klausmeier": ("`+experiment=klausmeier_bands` — vegetation bands on a slope (water flows towards "
                         "−x; absorbing layers at both ends): the bands' mean spacing against the fastest-growing "
                         "wavelength of the linear theory.", [
        (["+experiment=klausmeier_bands"], band_profile, ["bands", "band_spacing", "fastest_growing_wavelength"],
         band_spacing),
    ]),
    "model_cahn_hilliard": ("`+experiment=cahn_hilliard_coarsening` — phase separation and coarsening; the mass "
                            "is conserved and the free energy falls.", [
        (["+experiment=cahn_hilliard_coarsening"], "c_snapshots", ["mass", "free_energy", "c_min", "c_max"], None),
    ]),
    "model_halfar": ("`app=halfar` — the CISM v2.1 Halfar dome at 4 km after 200 years (semi-implicit): the "
                     "thickness error against Halfar's solution, largest at the margin.", [
        (["app=halfar"], "H_error", ["rms_error_m", "max_error_ice_m", "min_thickness_m", "grid_spacing_m"], None),
    ]),
    "model_darcy": ("`app=darcy` — Darcy flow in mixed form (flux u an `n-1` form, pressure p an `n` form, one "
                    "block system) on the default square: the pressure in colour, the velocity (the Raviart–Thomas "
                    "field of u) as arrows; the refinements on the square and the box are `darcy_convergence`.", [
        (["app=darcy"], "flow", ["pressure_l2_error_rel", "flux_l2_error_rel", "divergence_residual", "n_vertices"],
         None),
    ]),
    "model_shallow_water": ("`app=shallow_water` — Williamson's test case 2 (steady zonal geostrophic flow) after 5 "
                            "days of TRiSK in the model language (RK4, dt = 1600 s) on the icosphere of the Earth's "
                            "radius, subdiv 4: the depth's error against the exact (initial) state, a longitude–"
                            "latitude map.", [
        (["app=shallow_water"], "depth_error", ["l2_h", "linf_h", "mass_drift", "n_vertices"], None),
    ]),
    "model_shallow_water_cases": ("Williamson's test case 5 (`+experiment=williamson_tc5` at its defaults: zonal flow "
                                  "over a conical mountain, subdiv 5): the depth minus the T170 spectral reference at "
                                  "the end (m); and Galewsky's jet (`+experiment=galewsky` "
                                  "at its defaults, subdiv 5): the relative vorticity at day 6 (s⁻¹) over the northern "
                                  "hemisphere.", [
        (["+experiment=williamson_tc5"], "depth_error", ["l2_h", "linf_h", "mass_drift", "n_vertices"], None),
        (["+experiment=galewsky"], "vorticity_map", ["vorticity_max", "mass_drift", "n_vertices"], None),
    ]),
}


#: figures the docs pages show outside the gallery: docs/figures/<file> ← (overrides, figure stem)
PAGE_FIGURES = {
    "smoothing_default.png": ([], "smoothing"),
    "smoothing_bunny_default.png": (["mesh=bunny"], "smoothing"),
    "smoothing_bone_degenerate.png": (["mesh=sample", "mesh.sample=bone", "app.dt=0.05"], "smoothing"),
    "hodge_torus.png": (["app=hodge", "mesh=torus", "mesh.noise=0.05", "app.analytic=mixed"], "hodge_parts"),
    "hodge_sphere.png": (["app=hodge", "app.analytic=mixed"], "hodge_parts"),
    "parametrization_bunny_floater.png": (["app=parametrization", "mesh=sample", "mesh.sample=bunny10k_textured",
                                           "app.border=circle", "app.weights=mean_value"], "uv_layout"),
}


def sections() -> list[tuple[str, str, list, str | None]]:
    """Every section of the page in order: (name, caption, entries, experiment) — the experiment
    ``+experiment=<name>`` for a thesis figure, None for a model section (its entries' overrides
    say what runs). An entry is (overrides, figure, numbers shown[, derived])."""
    return ([(name, caption, entries, name) for name, (caption, entries) in GALLERY.items()]
            + [(name, caption, entries, None) for name, (caption, entries) in MODELS.items()])


def entry_overrides(experiment: str | None, overrides: list[str]) -> list[str]:
    """The overrides of an entry's command ``decrun <these>`` (as shown under its figure)."""
    return [*([f"+experiment={experiment}"] if experiment else []), *overrides]


def derived_of(entry):
    """An entry's derived-numbers function (``derived(run) -> dict``), or None."""
    return entry[3] if len(entry) > 3 else None


def run_entry(experiment: str | None, overrides: list[str], figure, scratch: Path, target: Path,
              derived=None) -> dict:
    """One single run (of ``+experiment=<experiment>`` unless None); copies ``<figure>.png``
    to ``target`` (or draws it, when ``figure`` is a function of the run); returns the metrics
    (and ``derived(run)``'s numbers)."""
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment, write

    cfg = compose_config(entry_overrides(experiment, overrides))
    out = Path(tempfile.mkdtemp(dir=scratch))
    done = run_experiment(cfg, out=out)
    write(done)
    result = done.result
    if callable(figure):  # drawn here from the run (a figure the app does not make)
        figure(done, target)
    else:
        shutil.copyfile(out / f"{figure}.png", target)
    return {**result.metrics, **(derived(done) if derived else {})}


def _section(name: str, caption: str, entries, experiment: str | None) -> list[str]:
    lines = [f"## {name}", "", caption, ""]
    cells, notes = [], []
    for n, (overrides, _, shown, *_) in enumerate(entries):
        file = f"{name}__{n}.png"
        cells.append(f"![{name} {' '.join(overrides)}](gallery/{file})")
        notes.append(f"`{' '.join(['decrun', *entry_overrides(experiment, overrides)])}`: " + ", ".join(
            f"{k} = {{{{ numbers.gallery_{name}__{n}.{k} }}}}" for k in shown))
    lines += ["| " + " | ".join(cells) + " |", "|" + "---|" * len(cells), ""]
    return lines + [f"- {note}" for note in notes] + [""]


#: the longitude–latitude maps of the shallow-water test cases' initial states, drawn from their
#: formulas by scripts/sphere_maps.py (not runs: the shallow-water model is issue 49's)
SPHERE_MAPS = ("sphere_tc5_surface.png", "sphere_galewsky_vorticity.png")


def _sphere_section() -> list[str]:
    cells = [f"![{name[:-4]}](gallery/{name})" for name in SPHERE_MAPS]
    return ["## Sphere maps", "", "Longitude–latitude maps as the shallow-water papers draw them (a model asks for one "
            "with `plots: {map: h}` or `{error_map: h, reference: h_exact}`, docs/models.md, \"Outputs\"): "
            "Williamson's test case 5, the free surface h + b with the mountain dashed, and Galewsky's jet, its "
            "relative vorticity per triangle (contours every 2e-5 s⁻¹ from −1e-4 to 1e-4, 0°–90°N), both at day 0 "
            "on an icosphere of subdiv 5 and the Earth's radius, drawn from the formulas by "
            "`python scripts/sphere_maps.py`.", "",
            "| " + " | ".join(cells) + " |", "|" + "---|" * len(cells), ""]


def page() -> str:
    """The text of gallery.md, written from the tables alone (no run): the numbers under each
    figure are placeholders, ``{{ numbers.gallery_<section>__<n>.<number> }}``, which the docs build
    fills from ``docs/numbers.json`` (``scripts/doc_numbers.py`` runs the same runs, a model entry's
    derived numbers included; ``tests/test_numbers.py`` checks them)."""
    lines = ["# Gallery", "", "One figure (or a pair to compare) per experiment of `conf/experiment/` and per shipped "
             "model of `conf/app/`, regenerated by `python scripts/gallery.py`. Each image is a single run of the "
             "command under it; the numbers are that run's (`docs/numbers.json`, made by "
             "`python scripts/doc_numbers.py --only gallery`).", ""]
    for name, caption, entries, experiment in sections():
        lines += _section(name, caption, entries, experiment)
    lines += _sphere_section()
    return "\n".join(lines)


def build(out: Path, only: list[str] | None = None) -> Path:
    """Run the entries of the sections named in ``only`` (default: all, and the pages' figures)
    into ``out/gallery/*.png`` and write ``out/gallery.md`` (always every section, from the tables:
    the figures of the sections not named stay as they are); returns the .md path."""
    images = out / "gallery"
    images.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as scratch:
        for name, _, entries, experiment in sections():
            if only and name not in only:
                continue
            for n, entry in enumerate(entries):
                overrides, figure = entry[0], entry[1]
                extra = ["app.animation=false"] if experiment is None else []  # a model's GIF is not shown
                start = time.perf_counter()
                run_entry(experiment, [*overrides, *extra], figure, Path(scratch), images / f"{name}__{n}.png",
                          derived_of(entry))
                print(f"gallery: {name} {' '.join(overrides)} ({time.perf_counter() - start:.1f} s)",
                      file=sys.stderr)
        if not only or "sphere_maps" in only:
            import importlib.util

            spec = importlib.util.spec_from_file_location("sphere_maps", Path(__file__).with_name("sphere_maps.py"))
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            module.main(["--out", str(images)])
        if not only:
            (out / "figures").mkdir(exist_ok=True)
            for name, (overrides, figure) in PAGE_FIGURES.items():
                run_entry(None, overrides, figure, Path(scratch), out / "figures" / name)
    path = out / "gallery.md"
    path.write_text(page())
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs"))
    parser.add_argument("--only", nargs="*", help="sections to regenerate, e.g. fig5_8_t_hole model_halfar sphere_maps "
                        "(default: all)")
    args = parser.parse_args(argv)
    print(build(Path(args.out), args.only))
    return 0


if __name__ == "__main__":
    sys.exit(main())
