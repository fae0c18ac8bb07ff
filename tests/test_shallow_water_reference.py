"""The stored spectral shallow-water references (benchmarks/data/, written by
benchmarks/shallow_water_spectral.py) and their numpy-only reader (benchmarks/shallow_water_reference.py):
the files match the manifest's sha256, the Legendre evaluator reproduces the solver's own (ducc0) grid
synthesis and TC2's closed form, TC5's day 15 has the published range and the initial mass."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import shallow_water_reference as swr  # noqa: E402

MANIFEST = json.loads(swr.MANIFEST.read_text())["files"]


def grid_sample(reference: swr.Reference, stride: int = 8):
    """Every ``stride``-th ring and longitude of the stored Gauss grid: (latitude, longitude, h) flattened."""
    rings = np.arange(0, reference.grid_latitude.size, stride)
    columns = np.arange(0, reference.grid_longitude.size, stride)
    latitude = np.repeat(reference.grid_latitude[rings], columns.size)
    longitude = np.tile(reference.grid_longitude[columns], rings.size)
    return latitude, longitude, reference.h_grid[np.ix_(rings, columns)].ravel()


def to_points(latitude: np.ndarray, longitude: np.ndarray) -> np.ndarray:
    """(n, 3) points on the sphere of radius a with longitude atan2(y, x)."""
    return swr.EARTH_RADIUS * np.column_stack([np.cos(latitude) * np.cos(longitude),
                                               np.cos(latitude) * np.sin(longitude), np.sin(latitude)])


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_every_stored_file_matches_its_sha256(name):
    assert swr.sha256_of(swr.DATA_DIR / name) == MANIFEST[name]["sha256"]
    assert MANIFEST[name]["command"].startswith("python benchmarks/shallow_water_spectral.py ")
    assert MANIFEST[name]["lmax"] >= 170


def test_a_corrupted_file_is_one_error_naming_it_and_its_command(tmp_path):
    name = swr.reference_name("tc5", 15)
    shutil.copy(swr.MANIFEST, tmp_path / swr.MANIFEST.name)
    data = bytearray((swr.DATA_DIR / name).read_bytes())
    data[-100] ^= 0xFF
    (tmp_path / name).write_bytes(bytes(data))
    with pytest.raises(swr.ReferenceFileError) as error:
        swr.load_reference(name, data_dir=tmp_path)
    message = str(error.value)
    assert name in message and MANIFEST[name]["command"] in message and "\n" not in message


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_the_legendre_evaluator_reproduces_the_stored_gauss_grid(name):
    """numpy recurrences vs ducc0's synthesis at the grid's points: one convention, to round-off."""
    reference = swr.load_reference(name)
    latitude, longitude, stored = grid_sample(reference)
    evaluated = reference.depth(latitude, longitude)
    assert np.max(np.abs(evaluated - stored)) < 1e-10 * np.max(np.abs(stored))
    through_points = swr.reference_depth(reference.case, reference.day, to_points(latitude, longitude)) \
        if reference.case != "tc2" else evaluated
    assert np.max(np.abs(through_points - stored)) < 1e-10 * np.max(np.abs(stored))


def test_tc2_over_the_poles_evaluated_from_its_coefficients_is_the_closed_form():
    """TC2 at α = π/4 (m = 0, 1, 2 terms) after 5 days: the stored coefficients, evaluated at random points,
    equal the closed-form steady state — colatitude, longitude origin, normalization and the phase agree."""
    reference = swr.load_reference(swr.reference_name("tc2", 5, alpha=np.pi / 4))
    rng = np.random.default_rng(7)
    latitude, longitude = np.arcsin(rng.uniform(-1, 1, 500)), rng.uniform(0, 2 * np.pi, 500)
    # the flow's poles (λ = π, θ = π/4 and λ = 0, θ = −π/4), where the depth is lowest
    latitude, longitude = np.r_[latitude, np.pi / 4, -np.pi / 4], np.r_[longitude, np.pi, 0.0]
    points = to_points(latitude, longitude)
    lat_back, lon_back = swr.spherical_coordinates(points)
    exact = swr.tc2_state(lat_back, lon_back, np.pi / 4)[2]
    assert np.max(np.abs(reference.depth(lat_back, lon_back) - exact)) < 1e-9 * np.max(exact)
    u0 = 2 * np.pi * swr.EARTH_RADIUS / (12 * swr.DAY)
    lowest = (2.94e4 - (swr.EARTH_RADIUS * swr.OMEGA * u0 + u0 ** 2 / 2)) / swr.GRAVITY
    assert exact.min() == pytest.approx(lowest, rel=1e-14) and 1092 < lowest < 1093


def test_tc5_day15_has_the_published_range_and_the_initial_mass():
    """Williamson et al. (1992) / Jakob-Chien et al. (1995): the free surface h + b at day 15 spans
    about 5050–5950 m; the spectral scheme conserves mass exactly (its l = 0 coefficient never changes)."""
    reference = swr.load_reference(swr.reference_name("tc5", 15))
    latitude = reference.grid_latitude[:, None] + 0.0 * reference.grid_longitude
    longitude = reference.grid_longitude[None, :] + 0.0 * latitude
    surface = reference.h_grid + swr.tc5_mountain(latitude, longitude)
    assert 5000.0 < surface.min() < 5080.0 and 5920.0 < surface.max() < 5960.0
    area = reference.gauss_weights[:, None] + 0.0 * longitude
    initial = swr.tc5_state(latitude, longitude)[2]
    assert abs(np.sum(area * reference.h_grid) / np.sum(area * initial) - 1.0) < 1e-13
    assert reference.entry["mass_relative_drift"] == pytest.approx(0.0, abs=1e-14)


def test_tc6_keeps_its_wavenumber_4_pattern():
    """TC6 at days 10 and 14: the depth along the equator is dominated by wavenumber 4 (eastward moving)."""
    for day in (10, 14):
        reference = swr.load_reference(swr.reference_name("tc6", day))
        longitude = np.linspace(0, 2 * np.pi, 256, endpoint=False)
        ring = reference.depth(np.full(256, np.pi / 4), longitude)
        spectrum = np.abs(np.fft.rfft(ring - ring.mean()))
        assert np.argmax(spectrum) == 4 and spectrum[4] > 5 * np.max(np.delete(spectrum, 4))


def test_williamson_norms_of_a_relative_perturbation():
    rng = np.random.default_rng(3)
    h_true, area = rng.uniform(1000, 2000, 200), rng.uniform(0.5, 1.5, 200)
    norms = swr.williamson_norms(h_true * 1.001, h_true, area)
    assert norms == pytest.approx({"l1": 1e-3, "l2": 1e-3, "linf": 1e-3}, rel=1e-9)
    spike = h_true.copy()
    spike[17] += 50.0
    norms = swr.williamson_norms(spike, h_true, area)
    assert norms["l1"] == pytest.approx(area[17] * 50 / np.sum(area * h_true))
    assert norms["l2"] == pytest.approx(np.sqrt(area[17]) * 50 / np.sqrt(np.sum(area * h_true ** 2)))
    assert norms["linf"] == pytest.approx(50 / h_true.max())


def test_points_off_the_sphere_are_refused_in_one_line():
    points = to_points(np.array([0.1, 0.2]), np.array([1.0, 2.0])) * 1.01
    with pytest.raises(ValueError, match="not on the sphere of radius 6371220.0 m") as error:
        swr.spherical_coordinates(points)
    assert "\n" not in str(error.value)
    with pytest.raises(swr.ReferenceFileError, match="no stored reference for case='tc5' day=3"):
        swr.reference_name("tc5", 3)


@pytest.mark.slow
def test_the_solver_keeps_tc2_steady_to_round_off(tmp_path):
    """benchmarks/shallow_water_spectral.py at T42, 1 day, α = 0 and π/4: l2(h) at round-off."""
    pytest.importorskip("ducc0")
    import shallow_water_spectral as solver

    for alpha in (0.0, np.pi / 4):
        args = solver.parse_arguments(["--case", "tc2", "-T", "42", "--days", "1", "--alpha", str(alpha),
                                       "--output", str(tmp_path / "tc2.npz")])
        written = solver.run(args, "test")
        assert written[str(tmp_path / "tc2.npz")]["tc2_norms"]["l2"] < 1e-13


@pytest.mark.slow
def test_the_solver_refuses_a_dt_over_its_cfl_limit_and_names_one_that_works(tmp_path):
    """RK4 at T42 with dt = 1800 s is past (|u| + √(g h)) √(T(T+1))/a · dt ≤ 2.8: one line naming a --dt,
    and that --dt runs."""
    pytest.importorskip("ducc0")
    import shallow_water_spectral as solver

    arguments = ["--case", "tc5", "-T", "42", "--days", "0.25", "--scheme", "rk4", "--output", str(tmp_path / "tc5.npz")]
    with pytest.raises(SystemExit) as error:
        solver.run(solver.parse_arguments([*arguments, "--dt", "1800"]), "test")
    message = str(error.value)
    assert "Courant number" in message and "\n" not in message
    suggested = message.split("pass --dt ")[1]
    written = solver.run(solver.parse_arguments([*arguments, "--dt", suggested]), "test")
    assert written[str(tmp_path / "tc5.npz")]["dt"] == float(suggested)
