"""Extending decrun without touching its code: a Hodge-star variant and an application from a
module outside the package plus one YAML file each, found through ``hydra.searchpath`` and
run by the real ``decrun`` command (the README's "Extending decrun" recipe)."""

from __future__ import annotations

import json

PLUGIN = '''
from dataclasses import dataclass

import numpy as np

from decrun.apps.base import App, Figure, Result
from decrun.core.stars import HodgeStar


@dataclass
class UniformStar(HodgeStar):
    """⋆_k = weight on every simplex (a toy variant)."""

    name = "uniform"
    weight: float = 2.0

    def diagonal(self, dec, k):
        return np.full(dec.K.num_simplices(k), self.weight)


@dataclass
class EulerApp(App):
    """Reports χ and Σ⋆0; records one series."""

    name = "euler"
    scale: float = 1.0

    def run(self, ctx):
        K = ctx.complex
        for step in range(3):
            ctx.record(step, chi=float(K.euler_characteristic) * step)
        stiffness = ctx.dec.laplacian_symmetric(0)
        return Result(metrics={"euler_characteristic_scaled": K.euler_characteristic * self.scale,
                               "star0_sum": float(ctx.dec.star_diagonal(0).sum()),
                               "stiffness_row_sum_max": float(abs(stiffness.sum(axis=1)).max())},
                      figures={"mesh": Figure("decrun.runner.plots.common.surface_figure",
                                              dict(vertices=K.vertices, faces=K.oriented_simplices()))})
'''


def test_a_toy_star_and_a_toy_app_run_through_the_cli(tmp_path, decrun_cli):
    (tmp_path / "toy_plugins.py").write_text(PLUGIN)
    conf = tmp_path / "toy_conf"
    (conf / "operator").mkdir(parents=True)
    (conf / "app").mkdir()
    (conf / "operator" / "uniform.yaml").write_text("_target_: toy_plugins.UniformStar\nweight: 2.0\n")
    (conf / "app" / "euler.yaml").write_text("_target_: toy_plugins.EulerApp\nscale: 1.0\n")
    proc = decrun_cli(f"hydra.searchpath=[file://{conf}]", "operator=uniform", "app=euler", "operator.weight=3.0",
                      "app.scale=2.0", "mesh.subdiv=1", env={"PYTHONPATH": str(tmp_path)})
    assert proc.returncode == 0, proc.stderr
    run = next((tmp_path / "outputs" / "runs").iterdir())
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["euler_characteristic_scaled"] == 4.0  # χ(sphere) = 2, scale 2
    assert metrics["star0_sum"] == 3.0 * 42  # ⋆0 = weight on each of the 42 vertices
    assert metrics["stiffness_row_sum_max"] < 1e-12  # d0ᵀ ⋆1 d0 annihilates constants
    assert (run / "mesh.png").is_file()
    from decrun.runner.results import read_result

    series = read_result(run / "result.h5").series
    assert list(series["chi"]) == [0.0, 2.0, 4.0] and list(series["step"]) == [0, 1, 2]
    # a misspelt option of the toy plugin is rejected with the toy's own option list
    bad = decrun_cli(f"hydra.searchpath=[file://{conf}]", "app=euler", "+app.scael=2", env={"PYTHONPATH": str(tmp_path)})
    assert bad.returncode == 1 and "app.scael: unknown option of app=euler; it has ['scale']" in bad.stderr


def test_plugin_yaml_without_target_or_with_a_wrong_class_is_a_clear_error(tmp_path, decrun_cli):
    conf = tmp_path / "bad_conf" / "operator"
    conf.mkdir(parents=True)
    (conf / "nothing.yaml").write_text("weight: 1.0\n")
    (conf / "wrong.yaml").write_text("_target_: decrun.core.solvers.cg.CGSolver\n")
    for option, words in (("nothing", "operator: the config node names no `_target_`"),
                          ("wrong", "operator._target_='decrun.core.solvers.cg.CGSolver' is not a HodgeStar")):
        proc = decrun_cli(f"hydra.searchpath=[file://{tmp_path / 'bad_conf'}]", f"operator={option}")
        assert proc.returncode == 1 and words in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr
