"""A pseudo-spectral vorticity–divergence shallow-water solver on the sphere: the independent reference for
Williamson's TC5 (day 15) and TC6 (days 10, 14) that decrun's DEC/TRiSK model is measured against.

The formulation is Williamson et al. (1992)'s STSWM / Hack & Jakob (1992): prognostic relative vorticity ζ,
divergence δ and depth h as spherical-harmonic coefficients (triangular truncation T), with η = ζ + f,
u the velocity and Φ = g (h + b):

    ∂ζ/∂t = −∇·(η u)
    ∂δ/∂t =  k·∇×(η u) − ∇²(g (h + b) + |u|²/2)
    ∂h/∂t = −∇·(h u)

u = k × ∇ψ + ∇χ with ∇²ψ = ζ, ∇²χ = δ (the inverse Laplacian −a²/(l(l+1)) per degree), synthesized as one
spin-1 field; the products η u, h u, |u|²/2 are formed on a Gauss–Legendre grid of ⌈(3T+1)/2⌉ × 2⌈(3T+1)/2⌉
points (alias-free for quadratic terms) and brought back by the scalar and spin-1 analyses, whose E/B
(gradient/curl) parts give divergences and curls exactly: for a tangent field A with spin-1 coefficients
(E, B), ∇·A ↦ −√(l(l+1)) E / a and k·∇×A ↦ −√(l(l+1)) B / a. Transforms: ``ducc0.sht`` (synthesis_2d /
analysis_2d, geometry "GL").

Time stepping: the stored TC5/TC6 references are ``--scheme rk4`` runs — explicit classical RK4 on the full
tendencies. The default ``--scheme leapfrog`` is the standard one of spectral models: semi-implicit leapfrog —
the gravity-wave terms g∇²h and H̄ δ (H̄ the largest initial depth) averaged over (n−1, n+1), all else
explicit at n — with the Robert–Asselin–Williams filter (ν = 0.02, α = 0.53; Williams 2011), started by four
RK4 substeps of dt/4. It is 4× cheaper per step but its phase error on advected small scales and on
gravity waves is of the size of the errors the reference must resolve (benchmarks/data/README.md: at T170
TC5's day 15 differs from RK4's by l2 8.6e-4 at dt 300 s); it kept TC2 steady to round-off.

dt: the leapfrog is stable for the explicitly treated advection while |u|max √(T(T+1)) dt / a < 1
(the highest wavenumber's advective frequency times dt); the default dt is the largest divisor of 3600 s at
which that Courant number is ≤ 0.5 with |u|max 1.2 times the initial largest speed (a margin for the flow's
growth). Every step checks the Courant number with the current largest speed and stops (one line, with a dt
that works) above 0.8. For RK4 the limit is the full gravity-wave frequency (|u| + √(g h))√(T(T+1))/a · dt ≤ 2.8.

Hyperdiffusion: ∂X/∂t = … − ν (∇⁴ − 4/a⁴) X on ζ and δ (the 4/a⁴ keeps rigid rotation, the l = 1 modes,
undamped; h is not diffused, so TC2's steady state is untouched). ν = a⁴ / (τ (T(T+1))²) with the e-folding
time τ = 6 h of the highest degree T: ν = 9.0e13 m⁴/s at T170, 1.4e15 at T85 (printed at start). It is
applied implicitly over the leapfrog's 2 dt (explicitly in RK4: ν(T(T+1)/a²)² dt ≪ 1).

    python benchmarks/shallow_water_spectral.py --case tc5 --truncation 170 --days 15 --scheme rk4 \\
        --dt 300 --threads 2 --output 'benchmarks/data/sw_tc5_T170_rk4_day{day}.npz' --manifest

writes the depth, free surface, ζ and δ coefficients and the depth on the Gauss grid at each day of ``--days``
(``{day}`` in ``--output`` is replaced by the day), and with ``--manifest`` records each file's sha256 and the
command in ``benchmarks/data/shallow_water_reference.json``. The stored references are read with
``shallow_water_reference.py`` (numpy only).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import ducc0.sht as sht
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import shallow_water_reference as swr  # noqa: E402

EARTH_RADIUS, GRAVITY, DAY = swr.EARTH_RADIUS, swr.GRAVITY, swr.DAY

#: the e-folding time (s) of the highest degree under the ∇⁴ hyperdiffusion
HYPERDIFFUSION_EFOLD = 6.0 * 3600.0
#: Robert–Asselin–Williams filter strength ν and its split α (α = 1 is the classical Robert–Asselin filter)
RAW_NU, RAW_ALPHA = 0.02, 0.53


@dataclass
class SpectralGrid:
    """Triangular truncation T on the Gauss–Legendre grid of ``nlat`` × ``nlon`` points (ducc0 order:
    colatitude from the north pole, longitude from 0 eastward)."""

    lmax: int
    nlat: int
    nlon: int
    nthreads: int = 1
    degree: np.ndarray = field(init=False)        # l of every coefficient, m-major
    order: np.ndarray = field(init=False)         # m of every coefficient
    latitude: np.ndarray = field(init=False)      # (nlat, 1) radians
    longitude: np.ndarray = field(init=False)     # (1, nlon) radians
    weights: np.ndarray = field(init=False)       # Gauss weights, Σ = 2

    def __post_init__(self):
        orders = np.concatenate([np.full(self.lmax + 1 - m, m) for m in range(self.lmax + 1)])
        self.order = orders
        self.degree = np.concatenate([np.arange(m, self.lmax + 1) for m in range(self.lmax + 1)])
        nodes, self.weights = np.polynomial.legendre.leggauss(self.nlat)
        self.latitude = np.arcsin(nodes[::-1])[:, None]          # north to south, as ducc0's rings
        self.weights = self.weights[::-1]
        self.longitude = (2.0 * np.pi * np.arange(self.nlon) / self.nlon)[None, :]

    @classmethod
    def alias_free(cls, lmax: int, nthreads: int = 1) -> SpectralGrid:
        """The grid that integrates cubic products of degree-T fields exactly: nlat ≥ (3T+1)/2, nlon = 2 nlat."""
        nlat = (3 * lmax + 1 + 1) // 2
        nlat += nlat % 2
        return cls(lmax, nlat, 2 * nlat, nthreads)

    def synthesis(self, alm: np.ndarray) -> np.ndarray:
        """Scalar coefficients → grid values (nlat, nlon)."""
        return sht.synthesis_2d(alm=alm[None], spin=0, lmax=self.lmax, geometry="GL", ntheta=self.nlat,
                                nphi=self.nlon, nthreads=self.nthreads)[0]

    def analysis(self, values: np.ndarray) -> np.ndarray:
        """Grid values → scalar coefficients (exact for band-limited fields; a Gauss quadrature otherwise)."""
        return sht.analysis_2d(map=values[None], spin=0, lmax=self.lmax, geometry="GL",
                               nthreads=self.nthreads)[0]

    def vector_synthesis(self, gradient_lm: np.ndarray, curl_lm: np.ndarray) -> np.ndarray:
        """Spin-1 synthesis: E, B coefficients → (A_ϑ, A_λ) = ∇(Σ E/√(l(l+1)) Y) + k × ∇(Σ B/√(l(l+1)) Y)
        on the unit sphere (ϑ colatitude: A_ϑ points south)."""
        return sht.synthesis_2d(alm=np.stack([gradient_lm, curl_lm]), spin=1, lmax=self.lmax, geometry="GL",
                                ntheta=self.nlat, nphi=self.nlon, nthreads=self.nthreads)

    def vector_analysis(self, south: np.ndarray, east: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Spin-1 analysis of the tangent field (A_ϑ, A_λ): its (E, B) coefficients."""
        coefficients = sht.analysis_2d(map=np.stack([south, east]), spin=1, lmax=self.lmax, geometry="GL",
                                       nthreads=self.nthreads)
        return coefficients[0], coefficients[1]


class ShallowWater:
    """The vorticity–divergence equations on ``grid`` with Coriolis parameter ``coriolis`` (nlat, nlon) and
    the bottom's coefficients ``bottom_lm`` (m); radius a, gravity g of Williamson et al. (1992)."""

    def __init__(self, grid: SpectralGrid, coriolis: np.ndarray, bottom_lm: np.ndarray, mean_depth: float,
                 efold: float = HYPERDIFFUSION_EFOLD):
        self.grid, self.coriolis, self.bottom_lm, self.mean_depth = grid, coriolis, bottom_lm, mean_depth
        self.efold = efold
        ell = grid.degree.astype(float)
        self.laplace = ell * (ell + 1.0)                              # −a² ∇² eigenvalues
        self.sqrt_laplace = np.sqrt(self.laplace)
        with np.errstate(divide="ignore"):
            self.inverse_sqrt = np.where(ell > 0, 1.0 / self.sqrt_laplace, 0.0)
        top = grid.lmax * (grid.lmax + 1.0)
        self.nu = EARTH_RADIUS ** 4 / (efold * top ** 2)
        # ν(∇⁴ − 4/a⁴): damping rate per degree, zero at l = 1
        self.damping = self.nu * (self.laplace ** 2 - 4.0) / EARTH_RADIUS ** 4

    def velocity(self, vorticity_lm: np.ndarray, divergence_lm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u eastward, v northward) in m/s on the grid from ζ, δ: ψ, χ = −a² (ζ, δ) / (l(l+1))."""
        south, east = self.grid.vector_synthesis(-EARTH_RADIUS * divergence_lm * self.inverse_sqrt,
                                                 -EARTH_RADIUS * vorticity_lm * self.inverse_sqrt)
        return east, -south

    def vorticity_divergence(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ζ, δ) coefficients (1/s) of the grid velocity (u, v)."""
        gradient, curl = self.grid.vector_analysis(-v, u)
        scale = self.sqrt_laplace / EARTH_RADIUS
        return -scale * curl, -scale * gradient

    def tendencies(self, state: tuple, diffuse: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(∂ζ/∂t, ∂δ/∂t, ∂h/∂t) of ``state`` = (ζ, δ, h) coefficients, with the hyperdiffusion if ``diffuse``."""
        vorticity_lm, divergence_lm, h_lm = state
        u, v = self.velocity(vorticity_lm, divergence_lm)
        eta = self.grid.synthesis(vorticity_lm) + self.coriolis
        h = self.grid.synthesis(h_lm)
        eta_gradient, eta_curl = self.grid.vector_analysis(-eta * v, eta * u)
        flux_gradient, _ = self.grid.vector_analysis(-h * v, h * u)
        kinetic_lm = self.grid.analysis(0.5 * (u ** 2 + v ** 2))
        scale = self.sqrt_laplace / EARTH_RADIUS
        d_vorticity = scale * eta_gradient
        d_divergence = (-scale * eta_curl
                        + self.laplace / EARTH_RADIUS ** 2 * (GRAVITY * (h_lm + self.bottom_lm) + kinetic_lm))
        d_h = scale * flux_gradient
        if diffuse:
            d_vorticity = d_vorticity - self.damping * vorticity_lm
            d_divergence = d_divergence - self.damping * divergence_lm
        return d_vorticity, d_divergence, d_h

    def rk4_step(self, state: tuple, dt: float) -> tuple:
        """One classical RK4 step of dt (s) on the full tendencies, hyperdiffusion explicit."""
        k1 = self.tendencies(state, True)
        k2 = self.tendencies(tuple(x + 0.5 * dt * k for x, k in zip(state, k1, strict=True)), True)
        k3 = self.tendencies(tuple(x + 0.5 * dt * k for x, k in zip(state, k2, strict=True)), True)
        k4 = self.tendencies(tuple(x + dt * k for x, k in zip(state, k3, strict=True)), True)
        return tuple(x + dt / 6.0 * (a + 2.0 * b + 2.0 * c + d) for x, a, b, c, d in zip(state, k1, k2, k3, k4, strict=True))

    def leapfrog_step(self, previous: tuple, current: tuple, dt: float) -> tuple:
        """Semi-implicit leapfrog: (n−1, n) → n+1, the gravity terms g∇²h, H̄δ averaged over n ± 1:
        δ⁺ − dt G h⁺ = δ⁻ + 2dt Nδ + dt G (h⁻ − 2hⁿ),  h⁺ + dt H̄ δ⁺ = h⁻ + 2dt Nh + dt H̄ (2δⁿ − δ⁻),
        G = g l(l+1)/a²; then the hyperdiffusion implicitly over 2 dt."""
        d_vorticity, d_divergence, d_h = self.tendencies(current, False)
        big_g = GRAVITY * self.laplace / EARTH_RADIUS ** 2
        depth = self.mean_depth
        rhs_divergence = previous[1] + 2.0 * dt * d_divergence + dt * big_g * (previous[2] - 2.0 * current[2])
        rhs_h = previous[2] + 2.0 * dt * d_h + dt * depth * (2.0 * current[1] - previous[1])
        divergence = (rhs_divergence + dt * big_g * rhs_h) / (1.0 + dt ** 2 * big_g * depth)
        h = rhs_h - dt * depth * divergence
        implicit = 1.0 / (1.0 + 2.0 * dt * self.damping)
        return (previous[0] + 2.0 * dt * d_vorticity) * implicit, divergence * implicit, h

    def max_speed(self, state: tuple) -> float:
        """Largest |u| (m/s) on the grid."""
        u, v = self.velocity(state[0], state[1])
        return float(np.sqrt(np.max(u ** 2 + v ** 2)))


def initial_spectral_state(model: ShallowWater, case: str, alpha: float):
    """(ζ, δ, h) coefficients of the case's closed-form state on the model's grid, and b's coefficients."""
    grid = model.grid
    u, v, h, _, b = swr.initial_state(case, grid.latitude + 0.0 * grid.longitude,
                                      grid.longitude + 0.0 * grid.latitude, alpha)
    vorticity_lm, divergence_lm = model.vorticity_divergence(u, v)
    bottom_lm = grid.analysis(b)
    # the depth from the smooth free surface minus the truncated bottom (TC5), as in STSWM
    return (vorticity_lm, divergence_lm, grid.analysis(h + b) - bottom_lm), bottom_lm


def default_dt(max_speed: float, lmax: int, scheme: str, max_depth: float) -> float:
    """The largest divisor of 3600 s with (1.2 |u|max) √(T(T+1)) dt / a ≤ 0.5 (leapfrog), or
    (1.2 |u|max + √(g h_max)) √(T(T+1)) dt / a ≤ 1.4 (RK4, half its imaginary-axis limit 2.83)."""
    wavenumber = np.sqrt(lmax * (lmax + 1.0)) / EARTH_RADIUS
    limit = (0.5 / (1.2 * max_speed * wavenumber) if scheme == "leapfrog"
             else 1.4 / ((1.2 * max_speed + np.sqrt(GRAVITY * max_depth)) * wavenumber))
    return largest_divisor_of_hour(limit)


def largest_divisor_of_hour(limit: float) -> float:
    """The largest divisor of 3600 s not above ``limit`` (s), so that every whole day is whole steps."""
    return float(max(d for d in range(1, 3601) if 3600 % d == 0 and d <= max(limit, 1.0)))


def save(path: Path, model: ShallowWater, state: tuple, case: str, day: float, meta: dict) -> None:
    """Write the coefficients (complex128), the depth on the Gauss grid (float64) and ``meta`` (JSON)."""
    grid = model.grid
    vorticity_lm, divergence_lm, h_lm = state
    surface_lm = h_lm + model.bottom_lm
    lat2d, lon2d = grid.latitude + 0.0 * grid.longitude, grid.longitude + 0.0 * grid.latitude
    b_exact = swr.initial_state(case, lat2d, lon2d, meta["alpha"])[4]
    h_grid = grid.synthesis(surface_lm) - b_exact if case == "tc5" else grid.synthesis(h_lm)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, lmax=grid.lmax, h_lm=h_lm, surface_lm=surface_lm, vorticity_lm=vorticity_lm,
                        divergence_lm=divergence_lm, h_grid=h_grid, grid_latitude=grid.latitude[:, 0],
                        grid_longitude=grid.longitude[0], gauss_weights=grid.weights,
                        meta=json.dumps(meta, sort_keys=True))


def record_in_manifest(path: Path, entry: dict) -> None:
    """Add or replace ``path``'s entry (sha256, command, case, day, ...) in the manifest beside the data."""
    manifest = json.loads(swr.MANIFEST.read_text()) if swr.MANIFEST.is_file() else {"files": {}}
    if path.resolve().parent != swr.MANIFEST.parent:
        raise SystemExit(f"--manifest records files of {swr.MANIFEST.parent} only; {path} is elsewhere")
    manifest["files"][path.name] = dict(entry, sha256=swr.sha256_of(path), bytes=path.stat().st_size)
    swr.MANIFEST.write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")


def parse_arguments(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--case", choices=["tc2", "tc5", "tc6"], required=True)
    parser.add_argument("--truncation", "-T", type=int, default=170, help="triangular truncation T")
    parser.add_argument("--days", type=float, nargs="+", required=True, help="output times (days)")
    parser.add_argument("--output", required=True, help="output .npz ('{day}' is replaced by each day)")
    parser.add_argument("--alpha", type=float, default=0.0, help="TC2's axis tilt (radians)")
    parser.add_argument("--scheme", choices=["leapfrog", "rk4"], default="leapfrog")
    parser.add_argument("--dt", type=float, default=None, help="time step (s); default: the CFL rule")
    parser.add_argument("--efold-hours", type=float, default=HYPERDIFFUSION_EFOLD / 3600.0,
                        help="the hyperdiffusion's e-folding time at degree T (hours)")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--manifest", action="store_true", help="record sha256 + command in the manifest")
    return parser.parse_args(argv)


def run(args: argparse.Namespace, command: str) -> dict:
    """Integrate ``args.case`` to every day of ``args.days``, writing one file per day; the run's numbers."""
    grid = SpectralGrid.alias_free(args.truncation, args.threads)
    lat2d, lon2d = grid.latitude + 0.0 * grid.longitude, grid.longitude + 0.0 * grid.latitude
    _, _, h0_grid, coriolis, _ = swr.initial_state(args.case, lat2d, lon2d, args.alpha)
    model = ShallowWater(grid, coriolis, np.zeros(1), float(np.max(h0_grid)), args.efold_hours * 3600.0)
    initial, model.bottom_lm = initial_spectral_state(model, args.case, args.alpha)
    speed0 = model.max_speed(initial)
    dt = args.dt or default_dt(speed0, grid.lmax, args.scheme, float(np.max(h0_grid)))
    wavenumber = np.sqrt(grid.lmax * (grid.lmax + 1.0)) / EARTH_RADIUS
    print(f"{args.case} T{grid.lmax} grid {grid.nlat}x{grid.nlon} scheme {args.scheme} dt {dt:g} s "
          f"nu {model.nu:.3g} m^4/s (e-folding {model.efold / 3600:g} h at l={grid.lmax}) "
          f"H {model.mean_depth:.1f} m |u|max {speed0:.2f} m/s", flush=True)
    targets = sorted(args.days)
    steps_at = [round(day * DAY / dt) for day in targets]
    for day, steps in zip(targets, steps_at, strict=True):
        if not np.isclose(steps * dt, day * DAY):
            raise SystemExit(f"--days {day:g} is not a whole number of steps of --dt {dt:g}: pass a divisor of it")
    mass0 = initial[2][0].real
    stepper = TimeStepper(model, initial, dt, args.scheme)
    started, written = time.perf_counter(), {}
    for day, target in zip(targets, steps_at, strict=True):
        while stepper.step < target:
            stepper.advance()
            if stepper.step == 1 or stepper.step % 50 == 0 or stepper.step == target:
                check_courant(model, stepper.current, dt, wavenumber, args.scheme, stepper.step)
            if stepper.step % round(DAY / dt) == 0:
                print(f"  day {stepper.step * dt / DAY:g} ({time.perf_counter() - started:.0f} s)", flush=True)
        current, step = stepper.current, stepper.step
        meta = {"case": args.case, "day": day, "alpha": args.alpha, "lmax": grid.lmax, "nlat": grid.nlat,
                "nlon": grid.nlon, "dt": dt, "scheme": args.scheme, "hyperdiffusion_nu": model.nu,
                "hyperdiffusion_efold_s": model.efold, "steps": step, "command": command,
                "mass_relative_drift": float((current[2][0].real - mass0) / mass0),
                "wall_s": time.perf_counter() - started}
        if args.case == "tc2":                      # the exact solution is the initial state
            area = grid.weights[:, None] + 0.0 * grid.longitude
            meta["tc2_norms"] = swr.williamson_norms(grid.synthesis(current[2]), h0_grid, area)
            print(f"TC2 day {day:g}: {meta['tc2_norms']}", flush=True)
        path = Path(args.output.replace("{day}", f"{day:g}"))
        save(path, model, current, args.case, day, meta)
        if args.manifest:
            record_in_manifest(path, meta)
        written[str(path)] = meta
        print(f"day {day:g}: step {step}, {meta['wall_s']:.1f} s wall, mass drift {meta['mass_relative_drift']:.2e}"
              f" -> {path}", flush=True)
    return written


class TimeStepper:
    """The state (ζ, δ, h) marched by dt: RK4, or the filtered semi-implicit leapfrog started by four RK4
    substeps of dt/4."""

    def __init__(self, model: ShallowWater, initial: tuple, dt: float, scheme: str):
        self.model, self.dt, self.scheme = model, dt, scheme
        self.previous, self.current, self.step = initial, initial, 0

    def advance(self) -> None:
        """One step of dt; the leapfrog's Robert–Asselin–Williams filter d = ν/2 (xⁿ⁻¹ − 2xⁿ + xⁿ⁺¹) moves
        xⁿ by α d and xⁿ⁺¹ by −(1 − α) d."""
        if self.scheme == "rk4" or self.step == 0:
            substeps = 1 if self.scheme == "rk4" else 4
            state = self.current
            for _ in range(substeps):
                state = self.model.rk4_step(state, self.dt / substeps)
            self.previous, self.current = self.current, state
        else:
            new = self.model.leapfrog_step(self.previous, self.current, self.dt)
            kick = [0.5 * RAW_NU * (p - 2.0 * x + n) for p, x, n in zip(self.previous, self.current, new, strict=True)]
            self.previous = tuple(x + RAW_ALPHA * d for x, d in zip(self.current, kick, strict=True))
            self.current = tuple(n - (1.0 - RAW_ALPHA) * d for n, d in zip(new, kick, strict=True))
        self.step += 1


def check_courant(model: ShallowWater, state: tuple, dt: float, wavenumber: float, scheme: str, step: int) -> None:
    """Stop (one line, with a dt that works) when the state is non-finite or the Courant number exceeds the
    scheme's limit: |u|max k_T dt ≤ 0.8 (leapfrog) or (|u|max + √(g hmax)) k_T dt ≤ 2.8 (RK4)."""
    speed = model.max_speed(state)
    h_max = float(np.max(model.grid.synthesis(state[2])))
    if not np.isfinite(speed) or not np.isfinite(h_max):
        raise SystemExit(f"the state is not finite at step {step}: pass a smaller --dt")
    frequency = speed * wavenumber if scheme == "leapfrog" else (speed + np.sqrt(GRAVITY * h_max)) * wavenumber
    limit = 0.8 if scheme == "leapfrog" else 2.8
    if frequency * dt > limit:
        raise SystemExit(f"Courant number {frequency * dt:.2f} > {limit} at step {step} (|u|max {speed:.1f} m/s): "
                         f"pass --dt {largest_divisor_of_hour(0.5 * limit / frequency):g}")


def main(argv: list[str] | None = None) -> None:
    """Entry point: parse, run, print."""
    args = parse_arguments(argv)
    command = "python benchmarks/shallow_water_spectral.py " + " ".join(
        shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv))
    run(args, command)


if __name__ == "__main__":
    main()
