"""Value-by-value functions of the coordinates the shallow-water test cases need in initial values
(``conf/experiment/williamson_tc5.yaml``, ``conf/experiment/galewsky.yaml``):

- ``arctan2(y, x)``: the angle of (x, y) in (−π, π] value by value — the longitude λ = arctan2(y, x),
  and TC5's λ − λc = arctan2(x, −y) wrapped about the mountain's centre λc = −π/2;
- ``latitude_integral(F)``: L(θ) = ∫_{−π/2}^{θ} F(θ') dθ' − ⟨∫_{−π/2}^{θ} F⟩, the integral along a meridian
  of an integrand F of the latitude alone, its area mean over the sphere removed
  (⟨g⟩ = ½ ∫_{−π/2}^{π/2} g(θ) cos θ dθ): the balanced depth of a zonal jet,
  g h = g h̄ − L(a u (f + u tan θ / a)) with h̄ the sphere's mean depth (Galewsky et al. 2004).

``latitude_integral`` is a function of the coordinates, not of a field: it stands in ``app.fields.<name>.initial``
(:class:`decrun.methods.model.initial.PointExpression` evaluates F on one meridian), and its typing rule refuses it
in an equation in one line.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.integrate import cumulative_simpson
from scipy.interpolate import CubicSpline

from decrun.methods.model.kinds import NUMBER, VECTOR

__all__ = ["built_in_operators", "latitude_integral", "LATITUDE_SAMPLES"]

#: latitudes of the composite Simpson rule on [−π/2, π/2] (odd: whole panels); the cubic spline through
#: the cumulative values is then evaluated at the points (error ~ (π/20000)⁴ F'''' for smooth F)
LATITUDE_SAMPLES = 20001


def latitude_integral(integrand: Callable[[np.ndarray], np.ndarray], points: np.ndarray, where: str,
                      samples: int = LATITUDE_SAMPLES) -> np.ndarray:
    """(n,) L(θ_i) = ∫_{−π/2}^{θ_i} F dθ' − ½ ∫_{−π/2}^{π/2} cos θ ∫_{−π/2}^{θ} F dθ' dθ at the latitudes
    θ_i = arcsin(z_i/|x_i|) of ``points`` (n, 3).

    ``integrand`` maps points (m, 3) to values (m,); it is evaluated on the meridians λ = 0 and λ = 1 of
    the sphere of the points' mean radius at ``samples`` latitudes (composite Simpson, cubic spline in
    between) and refused in one line naming ``where`` when the two meridians differ (F is not a function
    of the latitude alone) or a value is not finite.
    """
    from decrun.methods.model.language import ModelError

    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ModelError(f"{where}: latitude_integral needs points in R³ (a mesh on a sphere), got {points.shape[1:]}")
    radius = float(np.linalg.norm(points, axis=1).mean())
    lat = np.linspace(-0.5 * np.pi, 0.5 * np.pi, samples)
    values = []
    for lon in (0.0, 1.0):
        meridian = radius * np.column_stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
        values.append(np.broadcast_to(np.asarray(integrand(meridian), dtype=np.float64), lat.shape))
    first, second = values
    if not (np.isfinite(first).all() and np.isfinite(second).all()):
        raise ModelError(f"{where}: latitude_integral: the integrand is not finite on the meridian; "
                         "change the expression there")
    scale = max(float(np.abs(first).max()), np.finfo(float).tiny)
    if np.abs(first - second).max() > 1e-9 * scale:
        raise ModelError(f"{where}: latitude_integral(F) integrates a function of the latitude alone, but F differs "
                         "between the meridians λ = 0 and λ = 1; write F with arcsin(z/sqrt(x**2 + y**2 + z**2)) "
                         "only")
    cumulative = cumulative_simpson(first, x=lat, initial=0.0)
    cumulative -= 0.5 * float(cumulative_simpson(cumulative * np.cos(lat), x=lat)[-1])  # the area mean removed
    at = np.arcsin(np.clip(points[:, 2] / np.linalg.norm(points, axis=1), -1.0, 1.0))
    return CubicSpline(lat, cumulative)(at)


# ------------------------------------------------------------------ arctan2(y, x)
def _arctan2_kind(args, n):
    from decrun.methods.model.operators import Mismatch

    kinds = [kind for kind in args if kind != NUMBER]
    if any(kind == VECTOR for kind in kinds):
        raise Mismatch("arctan2 acts on numbers and forms value by value, not on a vector field")
    if len(set(kinds)) > 1:
        raise Mismatch(f"arctan2 takes forms of one kind, got a {kinds[0]} and a {kinds[1]}")
    return kinds[0] if kinds else NUMBER


def _arctan2_derivative(ops, kinds, values, i):
    y, x = (np.asarray(v, dtype=np.float64) for v in values)
    radius2 = x * x + y * y
    return x / radius2 if i == 0 else -y / radius2  # ∂/∂y atan2 = x/r², ∂/∂x = −y/r²


# ------------------------------------------------------------------ latitude_integral(F)
def _latitude_integral_kind(args, n):
    from decrun.methods.model.operators import Mismatch

    raise Mismatch("latitude_integral(F) is a function of the coordinates: use it in an initial value "
                   "(app.fields.<name>.initial), not in an equation")


def _latitude_integral_evaluate(ops, kinds, value):
    raise AssertionError("latitude_integral is evaluated by PointExpression (its typing rule refuses equations)")


def built_in_operators() -> list:
    """arctan2 and latitude_integral (:class:`~decrun.methods.model.operators.Operator`), registered as
    built-ins at the end of :mod:`decrun.methods.model.operators`."""
    from decrun.methods.model.operators import Operator

    return [
        Operator("arctan2", (2,), "two numbers or forms of one kind → the same",
                 "the angle of (x, y) = (second, first) in (−π, π] at each value (numpy's arctan2): "
                 "the longitude arctan2(y, x)",
                 _arctan2_kind, lambda ops, kinds, y, x: np.arctan2(y, x), derivative=_arctan2_derivative,
                 pointwise=True),
        Operator("latitude_integral", (1,), "an expression of the coordinates → a value (initial values only)",
                 "∫_{−π/2}^{θ} F dθ' along a meridian (composite Simpson on 20001 latitudes, cubic spline) minus its "
                 "area mean over the sphere; F a function of the latitude θ = arcsin(z/|x|) alone (refused "
                 "otherwise): a zonal jet's balanced depth",
                 _latitude_integral_kind, _latitude_integral_evaluate),
    ]
