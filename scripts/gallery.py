"""Regenerate the gallery: one figure (or a pair to compare) per thesis-figure experiment
(conf/experiment/fig*.yaml).

    python scripts/gallery.py [--out docs] [--only fig5_8_t_hole ...]

Each entry runs single runs of ``+experiment=<name>`` with a few overrides through the same
composition as ``decrun``, copies the named figure to ``<out>/gallery/<name>__<n>.png`` and
writes ``<out>/gallery.md`` with the images, the overrides and the metrics they show (as
placeholders the docs build fills from ``docs/numbers.json``: ``scripts/doc_numbers.py``).
Takes about a minute on two cores.
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


def run_entry(experiment: str | None, overrides: list[str], figure: str, scratch: Path, target: Path) -> dict:
    """One single run (of ``+experiment=<experiment>`` unless None); copies ``<figure>.png``
    to ``target``; returns the metrics."""
    from decrun.runner.config import compose_config
    from decrun.runner.run import run_experiment, write

    cfg = compose_config(([f"+experiment={experiment}"] if experiment else []) + list(overrides))
    out = Path(tempfile.mkdtemp(dir=scratch))
    done = run_experiment(cfg, out=out)
    write(done)
    result = done.result
    shutil.copyfile(out / f"{figure}.png", target)
    return result.metrics


def build(out: Path, only: list[str] | None = None) -> Path:
    """Run the entries (those of ``only``, default all) into ``out/gallery/*.png`` and write
    ``out/gallery.md`` (always every entry); returns the .md path.

    The numbers under each figure are placeholders, ``{{ numbers.gallery_<experiment>__<n>.<metric> }}``,
    which the docs build fills from ``docs/numbers.json`` (``scripts/doc_numbers.py`` runs the same
    runs; ``tests/test_numbers.py`` checks them), so the page never shows a number older than the code."""
    images = out / "gallery"
    images.mkdir(parents=True, exist_ok=True)
    lines = ["# Gallery", "", "One figure (or a pair to compare) per experiment of `conf/experiment/`, "
             "regenerated by `python scripts/gallery.py`. Each image is a single run of "
             "`decrun +experiment=<name> <overrides>`; the numbers are that run's metrics "
             "(`docs/numbers.json`, made by `python scripts/doc_numbers.py --only gallery`).", ""]
    with tempfile.TemporaryDirectory() as scratch:
        for experiment, (caption, entries) in GALLERY.items():
            lines += [f"## {experiment}", "", caption, ""]
            cells, notes = [], []
            for n, (overrides, figure, shown) in enumerate(entries):
                name = f"{experiment}__{n}.png"
                if not only or experiment in only:
                    start = time.perf_counter()
                    run_entry(experiment, overrides, figure, Path(scratch), images / name)
                    print(f"gallery: {experiment} {' '.join(overrides)} ({time.perf_counter() - start:.1f} s)",
                          file=sys.stderr)
                command = " ".join(["decrun", f"+experiment={experiment}", *overrides])
                cells.append(f"![{experiment} {' '.join(overrides)}](gallery/{name})")
                notes.append(f"`{command}`: " + ", ".join(
                    f"{k} = {{{{ numbers.gallery_{experiment}__{n}.{k} }}}}" for k in shown))
            lines += ["| " + " | ".join(cells) + " |", "|" + "---|" * len(cells), ""]
            lines += [f"- {note}" for note in notes] + [""]
        if not only:
            (out / "figures").mkdir(exist_ok=True)
            for name, (overrides, figure) in PAGE_FIGURES.items():
                run_entry(None, overrides, figure, Path(scratch), out / "figures" / name)
    path = out / "gallery.md"
    path.write_text("\n".join(lines))
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs"))
    parser.add_argument("--only", nargs="*", help="experiments to regenerate (default: all)")
    args = parser.parse_args(argv)
    print(build(Path(args.out), args.only))
    return 0


if __name__ == "__main__":
    sys.exit(main())
