"""``decrun app=<model> app.explain=true`` (issue 47): the compiled model's typed trees and block
structure on the console, through the real command, and nothing run — no step, no solve, no field."""

from __future__ import annotations

import json

import h5py

from cli_processes import decrun


def test_explain_prints_the_typed_trees_and_blocks_and_runs_nothing(tmp_path):
    done = decrun("app=gray_scott", "app.explain=true", "figures=false", "progress=false", "hydra.run.dir=gs",
                  cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    text = done.stderr
    # the typed tree: every node with its kind
    assert "app.equations[1]: dt(u) = Du*laplacian(u) - u*v**2 + F*(1 - u)" in text
    assert "laplacian : primal 0-form" in text and "Du : number" in text
    assert "fields: v : primal 0-form (evolved), u : primal 0-form (evolved)" in text
    assert "app.metrics.v_mean: integral(v) / integral(1 + 0*v)\n    / : number\n      integral : number" in text
    # the blocks: the constant Laplacian implicit, u v² nonlinear, F explicit
    assert "linear A_uu (constant coefficients, implicit): 256×256" in text
    assert "nonlinear (reads u, v): - u * v ** 2" in text and "explicit (reads no evolved field): + F * 1" in text
    metrics = json.loads((tmp_path / "gs" / "metrics.json").read_text())
    assert metrics["steps_done"] == 0 and metrics["status"] == "ok"
    with h5py.File(tmp_path / "gs" / "result.h5") as f:
        assert len(f["fields"]) == 0 and len(f["series"]) == 0


def test_explain_shows_a_systems_block_matrix(tmp_path):
    done = decrun("app=darcy", "app.explain=true", "figures=false", "progress=false", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "system for u, p: block matrix 1155×1155" in done.stderr
    assert "definition pressure : dual 0-form" in done.stderr
    assert "p : primal 2-form (computed by app.equations[0])" in done.stderr
    assert "   left side 2:\n    d : primal 2-form\n      u : primal 1-form\n   right side 2:\n    f : primal 2-form" \
        in done.stderr  # the system's second equation d(u) = f, typed


def test_explain_of_a_model_that_does_not_type_check_is_its_one_line_refusal(tmp_path):
    done = decrun("app=heat", "app.explain=true", "app.equations=['dt(u) = d(u)']", "figures=false", cwd=tmp_path)
    lines = [line for line in done.stderr.strip().splitlines() if line.strip()]
    assert done.returncode != 0 and len(lines) == 1
    assert lines[0].startswith("error: app.equations[0]: d(u) is a primal 1-form but dt(u) is a primal 0-form")


def test_explain_shows_border_terms_by_what_they_are_with_a_legend(tmp_path):
    """A Neumann and a Robin border rewrite laplacian(u) with names of their own: explain shows
    them as neumann_load(u), robin_load(u), robin_weight(u) — in the typed trees, the blocks and
    the definitions — each with one legend line naming its config key and expression, and no
    internal name (_neumann_u, _robin_alpha_u, _robin_value_u) anywhere."""
    common = ["app=heat", "mesh=grid", "mesh.nx=5", "mesh.ny=5", "app.explain=true", "figures=false", "progress=false"]
    neumann = decrun(*common, "+app.fields.u.neumann='x'", "hydra.run.dir=neumann", cwd=tmp_path)
    assert neumann.returncode == 0, neumann.stderr
    text = neumann.stderr
    assert "        inv_star : primal 0-form\n          neumann_load(u) : dual 2-form\n" in text
    assert "explicit (reads no evolved field): + k * inv_star(neumann_load(u))" in text
    assert ("  neumann_load(u) : dual 2-form: b_i = ∫_Γi g, the Neumann load of u (∂u/∂n = g, g = "
            "app.fields.u.neumann = x); laplacian(u) + inv_star(neumann_load(u)) is ⋆0⁻¹(−S u + b)\n") in text
    robin = decrun(*common, "+app.fields.u.robin={alpha: 2, value: 'x + t'}", "hydra.run.dir=robin", cwd=tmp_path)
    assert robin.returncode == 0, robin.stderr
    text = robin.stderr
    assert "          * : primal 0-form\n            robin_weight(u) : primal 0-form\n            u : primal 0-form" \
        in text
    assert "definition robin_load(u) : dual 2-form (a closure)" in text  # it reads t: a definition each step
    assert ("  robin_load(u) : dual 2-form: b_i = ∫_Γi v, the Robin load of u (∂u/∂n + α u = v, v = "
            "app.fields.u.robin.value = x + t); it reads t: evaluated again at every step\n") in text
    assert "  robin_weight(u) : primal 0-form: (∫_Γi α) / ⋆0_i, the Robin coefficient of u (α = " \
           "app.fields.u.robin.alpha = 2)" in text
    for shown in (neumann.stderr, robin.stderr):
        assert "_neumann_" not in shown and "_robin_" not in shown
    explained = json.loads((tmp_path / "robin" / "metrics.json").read_text())
    assert explained["steps_done"] == 0


def test_robin_borders_of_u_and_value_u_keep_their_terms_apart(tmp_path):
    """u's Robin load and value_u's Robin coefficient once shared the internal name _robin_value_u
    (a kind clash refused the model); each is now its own term, shown by what it is, and the model runs."""
    common = ["app=heat", "mesh=grid", "mesh.nx=5", "mesh.ny=5", "+app.fields.u.robin={alpha: 2, value: 'x'}",
              "+app.fields.value_u={form: 0, initial: 'y', robin: {alpha: 3, value: 'y'}}",
              "app.equations=['dt(u) = laplacian(u)', 'dt(value_u) = laplacian(value_u)']", "figures=false",
              "progress=false"]
    explained = decrun(*common, "app.explain=true", "hydra.run.dir=explained", cwd=tmp_path)
    assert explained.returncode == 0, explained.stderr
    for term in ("robin_load(u) : dual 2-form", "robin_weight(u) : primal 0-form", "robin_load(value_u) : dual 2-form",
                 "robin_weight(value_u) : primal 0-form"):
        assert f"  {term}: " in explained.stderr, term
    ran = decrun(*common, "app.t_end=0.01", "hydra.run.dir=ran", cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    alone = decrun(*common[:5], *common[7:], "app.t_end=0.01", "hydra.run.dir=alone", cwd=tmp_path)  # u only
    assert alone.returncode == 0, alone.stderr
    both, single = (json.loads((tmp_path / run / "metrics.json").read_text()) for run in ("ran", "alone"))
    for name in ("mass", "dirichlet_energy"):  # u's run is the same with value_u beside it, to round-off
        assert abs(both[name] - single[name]) <= 1e-12 * abs(single[name]), name
