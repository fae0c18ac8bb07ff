"""Mutation check: do the tests notice deliberate bugs? (issue 13; not part of the default run)

Each mutation below is one small, plausible bug — a flipped sign, a dropped condition, a step
that does nothing — written as exact text replacements in one file of ``decrun/``. For each,
the script copies the checkout (tracked and untracked, not ignored files) to a temporary
directory, applies the replacements there (the checkout itself is never touched), runs the
mutation's test selection with ``PYTHONPATH`` pointing at the copy, and counts the failing
tests. A mutation *survives* when no test fails. Before any mutation the unmutated copy must
pass every selection (otherwise a "kill" would mean nothing), and a replacement whose old
text is not found exactly once is an error (a stale mutation is reported, never skipped).

    .venv/bin/python benchmarks/mutation_check.py              # every mutation (~20 min)
    .venv/bin/python benchmarks/mutation_check.py -k flux      # mutations whose name has "flux"
    .venv/bin/python benchmarks/mutation_check.py --list

Prints one row per mutation: name, failing tests (unit / regression+CLI), the first failing
test ids, and exits 1 if any mutation survives.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# test selections (paths relative to the checkout; "-k" expressions allowed after them)
CORE = ["tests/core/test_dec.py", "tests/core/test_forms_hodge.py", "tests/core/test_boundary_flux.py"]
REG_SMOOTHING = ["tests/regression/test_regression.py", "-k", "smoothing"]
REG_PARAM = ["tests/regression/test_regression.py", "-k", "parametrization"]
REG_VECTOR = ["tests/regression/test_regression.py", "-k", "vector_field"]
REG_HODGE = ["tests/regression/test_regression.py", "-k", "hodge"]


@dataclass
class Mutation:
    name: str
    path: str  # file under the checkout
    replacements: list[tuple[str, str]]  # (old, new), each old text must occur exactly once
    selections: list[list[str]]  # pytest argument lists, run one after the other


MUTATIONS = [
    # ---------------------------------------------------------------- the list
    Mutation("is_embedding ignores border self-intersections", "decrun/methods/parametrization_metrics.py",
             [("    if border_self_intersections(uv, loops):\n        return False\n", ""),
              ("flips == 0 and degenerate == 0 and intersections == 0 and winding_ok",
               "flips == 0 and degenerate == 0 and winding_ok")],
             [["tests/methods/test_parametrization_metrics.py"], ["tests/runner/test_cli_signs.py", "-k", "overlapping"],
              REG_PARAM]),
    Mutation("degenerate_triangles always 0", "decrun/methods/parametrization_metrics.py",
             [("    return int(np.sum(np.abs(signed_uv_areas(uv, faces)) <= _degenerate_tolerance(uv)))",
               "    return 0")],
             [["tests/methods/test_parametrization_metrics.py"], REG_PARAM]),
    Mutation("implicit smoothing step does nothing", "decrun/methods/mean_curvature_flow.py",
             [("return self.solver.solve(self.M[:, None] * v)  # (M + dt S) v_{n+1} = M v_n", "return v")],
             [["tests/apps/test_smoothing.py"], REG_SMOOTHING]),
    Mutation("sign of the dual derivative d_dual", "decrun/core/dec.py",
             [("((-1) ** k * self.K.boundary(k))", "((-1) ** (k + 1) * self.K.boundary(k))")],
             [CORE, ["tests/runner/test_cli_signs.py", "-k", "reversed"], REG_VECTOR]),
    Mutation("source/sink sign in vector design", "decrun/methods/vector_design.py",
             [("np.add.at(s, np.asarray(vertices, dtype=np.int64), -np.asarray(outflow",
               "np.add.at(s, np.asarray(vertices, dtype=np.int64), np.asarray(outflow")],
             [["tests/apps/test_vector_field.py"], ["tests/runner/test_cli_signs.py", "-k", "reversed"], REG_VECTOR]),
    Mutation("smoothing blow-up check removed", "decrun/methods/mean_curvature_flow.py",
             [('if not reason and not self.now["roughness"] <= self.blowup_factor * first["roughness"]:',
               'if False:')],
             [["tests/apps/test_smoothing.py"], REG_SMOOTHING]),
    # ---------------------------------------------------------------- sign flips in the core
    Mutation("sign of d", "decrun/core/dec.py",
             [('lambda: self.K.incidence(k + 1))', 'lambda: -self.K.incidence(k + 1))')],
             [CORE, REG_PARAM]),
    Mutation("sign of every ⋆_k", "decrun/core/dec.py",
             [("np.asarray(self.star_variant.diagonal(self, k), dtype=np.float64)",
               "np.asarray(-self.star_variant.diagonal(self, k), dtype=np.float64)")],
             [CORE, REG_SMOOTHING]),
    Mutation("sign of ⋆_1 only", "decrun/core/dec.py",
             [("np.asarray(self.star_variant.diagonal(self, k), dtype=np.float64)",
               "np.asarray((-1.0 if k == 1 else 1.0) * self.star_variant.diagonal(self, k), dtype=np.float64)")],
             [CORE, REG_HODGE]),
    Mutation("sign of the codifferential", "decrun/core/dec.py",
             [("return (self.star_inv(k - 1) @ weak).tocsr()", "return (-(self.star_inv(k - 1) @ weak)).tocsr()")],
             [CORE, ["tests/apps/test_vector_field.py"], REG_VECTOR]),
    Mutation("sign of the border flux (§6.4.4)", "decrun/core/boundary/flux.py",
             [("dec.d(0).T @ dec.star(1) - border_vertex_matrix", "dec.d(0).T @ dec.star(1) + border_vertex_matrix")],
             [["tests/core/test_boundary_flux.py", "tests/apps/test_vector_field.py"], REG_VECTOR]),
    Mutation("rotation sign in the conformal border rows (eq. 5.9)", "decrun/methods/parametrization.py",
             [("vals = np.concatenate([ones, -ones + c, -c, s, -s, ones, -ones + c, -s, s, -c])",
               "vals = np.concatenate([ones, -ones + c, -c, -s, s, ones, -ones + c, s, -s, -c])")],
             [["tests/methods/test_parametrization.py"], REG_PARAM]),
    Mutation("circle border clockwise (thesis' (sin, cos))", "decrun/methods/parametrization.py",
             [("return np.column_stack([np.cos(angle), np.sin(angle)])",
               "return np.column_stack([np.sin(angle), np.cos(angle)])")],
             [["tests/methods/test_parametrization.py"], REG_PARAM]),
    Mutation("sign of the uv area in the Cauchy–Riemann border rows", "decrun/methods/parametrization.py",
             [("sp.bmat([[stiffness, -area_form], [-area_form.T, stiffness]])",
               "sp.bmat([[stiffness, area_form], [area_form.T, stiffness]])")],
             [["tests/methods/test_parametrization.py"], REG_PARAM]),
    # ---------------------------------------------------------------- further classic slips
    Mutation("explicit Euler runs the backward heat equation", "decrun/methods/mean_curvature_flow.py",
             [("return v - self.dt * (self.L @ v)  # v_{n+1} = v_n + dt Δ_M v_n", "return v + self.dt * (self.L @ v)")],
             [["tests/apps/test_smoothing.py"], REG_SMOOTHING]),
    Mutation("vertex normals point inwards", "decrun/core/geometry.py",
             [("face_normal = area_normals(points, f)  # length = 2 * area",
               "face_normal = -area_normals(points, f)")],
             [["tests/runner/mesh/test_meshes.py"], REG_SMOOTHING]),
    # ---------------------------------------------------------------- the fluid (issue 18)
    Mutation("fluid force with the wrong sign", "decrun/methods/fluid/simulation.py",
             [("w = w + self.dt * (self.d0T @", "w = w - self.dt * (self.d0T @")],
             [["tests/methods/test_fluid.py"], ["tests/apps/test_fluid_app.py"]]),
    Mutation("fluid keeps the mean vorticity on closed surfaces", "decrun/methods/fluid/simulation.py",
             [("        if not self.closed:\n            return w\n        return w - (self.star0 @ w) / self.star0.sum()",
               "        return w")],
             [["tests/methods/test_fluid.py"], ["tests/apps/test_fluid_app.py"]]),
    # ---------------------------------------------------------------- what the fluid computes (issue 25.7)
    Mutation("swept: 2nd triangle's mean of ω at p_b instead of p_b'", "decrun/methods/fluid/swept.py",
             [("second * (wa0 + wb1 + wa1) / 3.0", "second * (wa0 + wb0 + wa1) / 3.0")],
             [["tests/methods/test_fluid.py", "-k", "swept"]]),
    Mutation("swept: 2nd triangle (p_a, p_b', p_a') made (p_b, p_b', p_a')", "decrun/methods/fluid/swept.py",
             [("np.cross(b1 - a0, a1 - a0)", "np.cross(b1 - b0, a1 - b0)"),
              ("second * (wa0 + wb1 + wa1) / 3.0", "second * (wb0 + wb1 + wa1) / 3.0")],
             [["tests/methods/test_fluid.py", "-k", "swept"]]),
    Mutation("swept: 2nd triangle's area with p_b for p_b' (mean of ω kept)", "decrun/methods/fluid/swept.py",
             [("np.cross(b1 - a0, a1 - a0)", "np.cross(b0 - a0, a1 - a0)")],
             [["tests/methods/test_fluid.py", "-k", "swept"]]),
    Mutation("swept: 2nd triangle's mean of ω at p_b instead of p_a'", "decrun/methods/fluid/swept.py",
             [("second * (wa0 + wb1 + wa1) / 3.0", "second * (wa0 + wb1 + wb0) / 3.0")],
             [["tests/methods/test_fluid.py", "-k", "swept"]]),
    Mutation("shadow flag always stable", "decrun/methods/fluid/shadow.py",
             [('"perturbation_stable": bool(per_step <= self.max_growth_per_step)', '"perturbation_stable": True')],
             [["tests/apps/test_fluid_app.py", "-k", "shadow or chaotic or jump"]]),
    Mutation("shadow verdict from the run mean (the estimator before issue 25.2)", "decrun/methods/fluid/shadow.py",
             [("per_step = fitted_growth(points[:, 1], points[:, 0])", "per_step = self.log_growth / self.steps")],
             [["tests/apps/test_fluid_app.py", "-k", "shadow or chaotic or jump"]]),
    Mutation("fluid app ignores the shadow's verdict", "decrun/methods/fluid/metrics.py",
             [('"stable": bounded and chaos.get("perturbation_stable", True),', '"stable": bounded,')],
             [["tests/apps/test_fluid_app.py", "-k", "shadow or chaotic or jump"]]),
]


def copy_checkout(destination: Path) -> None:
    """Tracked and untracked (not ignored) files of the checkout, symlinks kept as links."""
    listing = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                             check=True, capture_output=True).stdout.decode().split("\0")
    for name in filter(None, listing):
        source = ROOT / name
        if not os.path.lexists(source):
            continue  # deleted in the work tree, not yet committed
        target = destination / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if source.is_symlink():
            os.symlink(os.readlink(source), target)
        else:
            shutil.copy2(source, target)


def apply(mutation: Mutation, copy: Path) -> None:
    path = copy / mutation.path
    text = path.read_text()
    for old, new in mutation.replacements:
        count = text.count(old)
        if count != 1:
            raise SystemExit(f"stale mutation {mutation.name!r}: {old!r} occurs {count} times in {mutation.path}")
        text = text.replace(old, new)
    path.write_text(text)


def run_tests(copy: Path, selection: list[str], timeout: float) -> tuple[int, int, list[str]]:
    """(passed, failed, failing test ids) of one pytest run inside ``copy``."""
    env = dict(os.environ, PYTHONPATH=str(copy), MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
    command = [sys.executable, "-m", "pytest", "-q", "-rfE", "-p", "no:cacheprovider", *selection]
    try:
        out = subprocess.run(command, cwd=copy, env=env, capture_output=True, text=True, timeout=timeout).stdout
    except subprocess.TimeoutExpired:
        return 0, 1, [f"TIMEOUT after {timeout:.0f}s: {' '.join(selection)}"]
    failing = re.findall(r"^(?:FAILED|ERROR) (\S+)", out, flags=re.M)
    summary = re.findall(r"(\d+) (passed|failed|error)", out.splitlines()[-1] if out.strip() else "")
    counts = {kind: int(n) for n, kind in summary}
    if not summary:
        return 0, 1, [f"no pytest summary for {' '.join(selection)}: {out[-300:]!r}"]
    return counts.get("passed", 0), counts.get("failed", 0) + counts.get("error", 0), failing


def check_copy_is_imported(copy: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(copy))
    where = subprocess.run([sys.executable, "-c", "import decrun; print(decrun.__file__)"], cwd=copy, env=env,
                           capture_output=True, text=True, check=True).stdout.strip()
    if not Path(where).resolve().is_relative_to(copy.resolve()):
        raise SystemExit(f"the tests would import decrun from {where}, not from the mutated copy {copy}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", default="", help="only mutations whose name contains this text")
    parser.add_argument("--list", action="store_true", help="list the mutations and exit")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per pytest run")
    parser.add_argument("--no-baseline", action="store_true", help="skip the unmutated run (trust it)")
    args = parser.parse_args()
    chosen = [m for m in MUTATIONS if args.k.lower() in m.name.lower()]
    if args.list:
        for m in chosen:
            print(f"{m.name:58s} {m.path}")
        return 0
    with tempfile.TemporaryDirectory(prefix="decrun-mutation-") as tmp:
        base = Path(tmp) / "base"
        copy_checkout(base)
        check_copy_is_imported(base)
        for m in chosen:  # stale replacements fail before any test runs
            probe = Path(tmp) / "probe"
            shutil.copytree(base, probe, symlinks=True)
            apply(m, probe)
            shutil.rmtree(probe)
        if not args.no_baseline:
            selections = {tuple(s) for m in chosen for s in m.selections}
            for selection in sorted(selections):
                passed, failed, failing = run_tests(base, list(selection), args.timeout)
                if failed:
                    print(f"baseline fails ({' '.join(selection)}): {failing[:5]}")
                    return 2
            print(f"baseline: all {len(selections)} selections pass unmutated")
        survivors = []
        print(f"{'mutation':58s} {'killed by':>10s}  first failing tests")
        for m in chosen:
            work = Path(tmp) / "mutant"
            shutil.copytree(base, work, symlinks=True)
            apply(m, work)
            start = time.perf_counter()
            unit = regression = 0
            failing_ids: list[str] = []
            for selection in m.selections:
                _, failed, failing = run_tests(work, selection, args.timeout)
                if selection[0].startswith("tests/regression") or "test_cli" in selection[0]:
                    regression += failed
                else:
                    unit += failed
                failing_ids += failing
            shutil.rmtree(work)
            killed = unit + regression
            if not killed:
                survivors.append(m.name)
            shown = ", ".join(t.split("::", 1)[-1] for t in failing_ids[:3])
            print(f"{m.name:58s} {unit:3d} + {regression:3d}   {shown if killed else 'SURVIVED'}"
                  f"  ({time.perf_counter() - start:.0f}s)", flush=True)
        print(f"\n{len(chosen) - len(survivors)} of {len(chosen)} mutations killed"
              + (f"; survivors: {survivors}" if survivors else "; no survivor"))
        return 1 if survivors else 0


if __name__ == "__main__":
    sys.exit(main())
