"""app=parametrization defaults: the conformal border is exact on developable patches and
near-exact on smooth height fields (reflex_rows=cauchy_riemann), the thesis' rule one
override away."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.apps.parametrization import Parametrization
from decrun.core.complex import SimplicialComplex
from decrun.runner.config import compose_config
from decrun.runner.run import run_experiment
from decrun.runner.plugins import option


def height_field(nx: int = 30) -> SimplicialComplex:
    """z = 0.15 sin(π(x + ½)) sin(π(y + ½)) over the 30 × 30 grid on [−½, ½]²: smooth, open."""
    m = option("mesh", "grid", nx=nx, ny=nx).load()
    V = m.vertices.copy()
    V[:, 2] = 0.15 * np.sin(np.pi * (V[:, 0] + 0.5)) * np.sin(np.pi * (V[:, 1] + 0.5))
    return SimplicialComplex(V, m.simplices)


def test_default_conformal_border_is_near_exact_on_a_smooth_height_field(run_app):
    K = height_field()
    default, _ = run_app(Parametrization(), K, star="mixed_area")
    thesis, _ = run_app(Parametrization(reflex_rows="harmonic"), K, star="mixed_area")
    free, _ = run_app(Parametrization(border="free"), K, star="mixed_area")
    assert Parametrization().reflex_rows == "cauchy_riemann"
    assert default.metrics["angle_distortion_mean_deg"] < 0.3  # measured 0.20°
    assert thesis.metrics["angle_distortion_mean_deg"] > 20  # measured 26.6°: cusps at reflex vertices
    assert free.metrics["angle_distortion_mean_deg"] < 0.15  # measured 0.09°
    assert default.metrics["is_embedding"] and default.metrics["cauchy_riemann_rows"] > 0


@pytest.mark.parametrize("rows, exact", [("cauchy_riemann", True), ("harmonic", False)])
def test_fig5_5_flat_mesh_is_reproduced_exactly_by_the_default_only(rows, exact):
    result, _, _ = run_experiment(compose_config(["+experiment=fig5_5_flat_hole", f"app.reflex_rows={rows}"]))
    error = result.metrics["angle_distortion_mean_deg"]
    assert (error < 1e-6) if exact else (error > 1.0)  # 3.7° with the thesis' harmonic rows
