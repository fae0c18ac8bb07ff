"""Composed models (docs/models.md, "Composed models"): parts in conf/app/parts/ that Hydra merges
into a model's node, sharing fields by name; conflicts refused naming both parts; a missing
part named with the parts there are; a part's constant overridden and swept from the real CLI;
the Halfar dome as halfar_dynamics + glen_law, equal to the one-file model."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from omegaconf import OmegaConf

from decrun import DEC, SimplicialComplex
from decrun.apps.model import Model
from decrun.errors import ConfigError
from decrun.runner.job.config import compose_config, load_option
from decrun.runner.job.plugins import option
from decrun.runner.job.run import run_experiment
from decrun.runner.mesh.sources.primitives import Grid

#: conf/app/halfar.yaml's equations before it was split into parts (the one-file model)
ONE_FILE_EQUATIONS = [
    "Gamma = 2*A*(rho*g)**n/(n + 2)",
    "grad2 = norm(sharp(d(H)))**2",
    "D = Gamma*average(cell_average(H)**(n + 2)*grad2**((n - 1)/2))",
    "dt(H) = -codifferential(D*d(H))",
    "t0 = (1/18)/Gamma*(7/4)**3*R0**4/H0**7",
    "s = t0/(t + t0)",
    "H_exact = H0*s**(1/9)*max(0, 1 - (s**(1/18)*sqrt((x - xc)**2 + (y - yc)**2)/R0)**((n + 1)/n))**(n/(2*n + 1))",
    "ice = max(sign(H_exact), 0)",
    "H_error = H - H_exact",
]


def grid_dec() -> DEC:
    mesh = Grid(nx=5, ny=5).make()
    return DEC(SimplicialComplex(mesh.vertices, mesh.faces))


def model(**options) -> Model:
    return Model(**{"equations": ["dt(u) = laplacian(u)"], "fields": {}, **options})


# ---------------------------------------------------------------- the merge
def test_halfar_is_its_two_parts_and_its_own_declarations_merged():
    app = option("app", "halfar")
    assert list(app.parts) == ["halfar_dynamics", "glen_law"]
    assert {"n", "A", "rho", "g", "R0", "H0"} <= set(app.constants)  # the parts' constants are the model's
    spec = app.spec()
    assert set(spec.equations) == set(ONE_FILE_EQUATIONS) and len(spec.equations) == len(ONE_FILE_EQUATIONS)
    assert spec.equations[:4] == ONE_FILE_EQUATIONS[1:4] + ONE_FILE_EQUATIONS[:1]  # parts in order, then the own
    assert spec.equation_keys[0] == "app.parts.halfar_dynamics.equations[0]"
    assert spec.equation_keys[3] == "app.parts.glen_law.equations[0]" and spec.equation_keys[4] == "app.equations[0]"
    # H: the part declares it, the model gives its initial value
    assert list(spec.fields) == ["H"] and spec.fields["H"].form == "0" and spec.fields["H"].initial.startswith("H0*")
    # --help and option() read the file as Hydra composes it
    assert OmegaConf.to_container(load_option("app", "halfar")) == \
        OmegaConf.to_container(compose_config(["app=halfar"]).app)


def test_the_composed_halfar_equals_the_one_file_model_at_4km():
    composed = compose_config(["app=halfar", "figures=false"])
    one_file = compose_config(["app=halfar", "figures=false"])
    one_file.app.constants = OmegaConf.to_container(composed.app.constants, resolve=True)  # glen_law's, as numbers
    one_file.app.parts = {}
    one_file.app.fields.H.form = 0
    one_file.app.equations = ONE_FILE_EQUATIONS
    a = run_experiment(composed).result.metrics
    b = run_experiment(one_file).result.metrics
    assert b["grid_spacing_m"] == pytest.approx(4000.0)
    for key in ("rms_error_m", "max_error_m", "max_error_ice_m", "volume_m3"):
        assert a[key] == pytest.approx(b[key], rel=1e-12, abs=1e-9), key
    assert a["rms_error_m"] == pytest.approx(11.99, abs=0.01)


def test_a_field_shared_by_parts_is_one_field_and_its_initial_value_comes_from_one():
    app = model(equations=[], fields={"u": {"form": "0", "initial": "x"}},
                parts={"a": {"fields": {"u": {"form": "0"}}, "equations": ["dt(u) = k*laplacian(u)"]},
                       "b": {"fields": {"u": {"form": 0}}, "equations": ["w = 2*u"], "metrics": {"m": "max(w)"}}},
                constants={"k": 1.0})
    spec = app.spec()
    assert spec.fields["u"].initial == "x" and spec.equations == ["dt(u) = k*laplacian(u)", "w = 2*u"]
    assert spec.metrics == {"m": "max(w)"}
    assert set(app.compiled(grid_dec()).kinds) >= {"u", "w", "k"}


# ---------------------------------------------------------------- conflicts name both parts
@pytest.mark.parametrize("parts, own, expected", [
    ({"p": {"fields": {"u": {"form": "0"}}, "equations": ["dt(u) = laplacian(u)"]},
      "q": {"fields": {"u": {"form": "1"}}}}, {},
     r"^app\.parts: field u is declared form 0 by part p and form 1 by part q; a field shared by parts has one form$"),
    ({"p": {"equations": ["dt(u) = laplacian(u)", "G = 1 + 0*u"]}, "q": {"equations": ["G = 2 + 0*u"]}}, {},
     r"^app\.parts: G is computed by part p \(G = 1 \+ 0\*u\) and by part q \(G = 2 \+ 0\*u\); a quantity has one "
     r"definition: drop one$"),
    ({"p": {"equations": ["dt(u) = laplacian(u)"]}}, {"equations": ["dt(u) = -u"]},
     r"^app\.parts: u is computed by part p .* and by the model's own \(app=model\) \(dt\(u\) = -u\)"),
    ({"p": {"fields": {"u": {"form": "0", "initial": "x"}}, "equations": ["dt(u) = laplacian(u)"]},
      "q": {"fields": {"u": {"form": "0", "initial": "y"}}}}, {},
     r"^app\.parts: field u gets its initial value from part p \('x'\) and from part q \('y'\); give it once$"),
    ({"p": {"equations": ["dt(u) = laplacian(u)"], "metrics": {"m": "max(u)"}}, "q": {"metrics": {"m": "min(u)"}}},
     {}, r"^app\.parts: metric m is 'max\(u\)' in part p and 'min\(u\)' in part q"),
    ({"p": {"equations": ["dt(u) = laplacian(u)"], "constants": {"n": 3.0}}, "q": {"constants": {"n": 4.0}}}, {},
     r"^app\.parts: constant n is 3\.0 in part p and 4\.0 in part q; a constant has one default: set it in the "
     r"model \(the model's value wins\), e\.g\. `app\.constants\.n=3\.0`$"),
])
def test_a_conflict_is_one_line_naming_both_parts(parts, own, expected):
    options = {"equations": [], "fields": {"u": {"form": "0", "initial": "x"}}, **own}
    with pytest.raises(ConfigError, match=expected) as refused:
        model(parts=parts, **options)
    assert "\n" not in str(refused.value)


def test_parts_constants_are_the_models_defaults_and_the_models_own_value_wins():
    parts = {"p": {"equations": ["dt(u) = k*laplacian(u)"], "constants": {"n": 3.0, "k": 1.0}},
             "q": {"constants": {"n": 4.0}}}
    app = model(equations=[], fields={"u": {"form": "0", "initial": "x"}}, parts=parts, constants={"n": 3.5})
    assert app.constants == {"n": 3.5, "k": 1.0}  # n: the model's, over both parts'; k: part p's default
    app = model(equations=[], fields={"u": {"form": "0", "initial": "x"}}, parts={"p": parts["p"]})
    assert app.constants == {"n": 3.0, "k": 1.0}


def test_an_error_inside_a_part_names_the_parts_key():
    app = model(equations=["v = 2*u"], fields={"u": {"form": "0", "initial": "x"}},
                parts={"p": {"equations": ["w = u", "dt(u) = laplacain(u)"]}})
    with pytest.raises(ConfigError, match=r"^app\.parts\.p\.equations\[1\]: unknown operator 'laplacain'"):
        app.compiled(grid_dec())
    with pytest.raises(ConfigError, match=r"^app\.equations\[0\]: "):  # the model's own keep their key
        model(equations=["v = d(u) + u"], fields={"u": {"form": "0", "initial": "x"}},
              parts={"p": {"equations": ["dt(u) = laplacian(u)"]}}).compiled(grid_dec())


def test_a_conflict_through_the_cli_is_refused_before_any_work(decrun_cli, tmp_path):
    done = decrun_cli("app=halfar", 'app.parts.glen_law.equations=["Gamma = 1", "D = 0*d(H)"]')
    assert done.returncode == 1
    assert done.stderr.strip().splitlines()[-1] == (
        "error: app.parts: D is computed by part halfar_dynamics (D = Gamma*average(cell_average(H)**(n + 2)*"
        "grad2**((n - 1)/2))) and by part glen_law (D = 0*d(H)); a quantity has one definition: drop one")
    done = decrun_cli("app=halfar", "+app.parts.glen_law.fields={H: {form: 1}}")
    assert done.returncode == 1 and done.stderr.strip().splitlines()[-1] == (
        "error: app.parts: field H is declared form 0 by part halfar_dynamics and form 1 by part glen_law; "
        "a field shared by parts has one form")
    assert not list(tmp_path.rglob("result.h5*"))


def test_two_parts_defaults_of_one_constant_through_the_cli_and_the_hint_runs(decrun_cli, tmp_path):
    """Hydra merges the parts' ``constants`` into the model's silently (the last part wins);
    the unresolved node still shows that app.constants.n is glen_law's interpolation, so the
    clash is refused — and once the model sets n (the hint), the model's value wins."""
    clash = "+app.parts.halfar_dynamics.constants={n: 4.0}"
    done = decrun_cli("app=halfar", clash, "app.t_end=2", "figures=false")
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        "error: app.parts: constant n is 4.0 in part halfar_dynamics and 3.0 in part glen_law; a constant has one "
        "default: set it in the model (the model's value wins), e.g. `app.constants.n=4.0`"]
    assert not list(tmp_path.rglob("result.h5*"))
    (tmp_path / "hint").mkdir()
    done = decrun_cli("app=halfar", clash, "app.constants.n=4.0", "app.t_end=2", "figures=false", cwd=tmp_path / "hint")
    assert done.returncode == 0, done.stderr
    (metrics,) = (tmp_path / "hint" / "outputs" / "runs").glob("*/metrics.json")
    assert OmegaConf.load(metrics.parent / ".hydra" / "config.yaml").app.constants.n == 4.0


# ---------------------------------------------------------------- a part that does not exist
def test_a_missing_part_is_one_line_with_the_parts_there_are(decrun_cli, tmp_path):
    done = decrun_cli("app=halfar", "app/parts@app=[halfar_dynamics,glen_lw]")
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        "error: app=halfar: no part glen_lw (app/parts/glen_lw.yaml is in no config directory of the search path); "
        "did you mean glen_law? (the parts: glen_law | halfar_dynamics)"]
    # a user's model in their own config directory, naming a part of theirs that is not there
    (tmp_path / "my_conf" / "app" / "parts").mkdir(parents=True)
    (tmp_path / "my_conf" / "app" / "parts" / "my_law.yaml").write_text("parts: {my_law: {equations: ['q = 1']}}\n")
    (tmp_path / "my_conf" / "app" / "dome.yaml").write_text(
        "defaults:\n  - _model\n  - parts@_here_: [halfar_dynamics, my_lw]\n  - _self_\nmodel: dome\n")
    done = decrun_cli("app=dome", "hydra.searchpath=[file://my_conf]")
    assert done.returncode == 1 and done.stderr.strip().splitlines()[-1] == (
        "error: app=dome: no part my_lw (app/parts/my_lw.yaml is in no config directory of the search path); "
        "did you mean my_law? (the parts: glen_law | halfar_dynamics | my_law)")
    assert not (tmp_path / "outputs").exists() or not list(tmp_path.rglob("result.h5*"))


# ---------------------------------------------------------------- a part's constant from the CLI
def test_a_parts_constant_is_overridden_and_swept_from_the_cli_without_a_plus(decrun_cli, tmp_path):
    short = ["app.t_end=20", "figures=false"]
    done = decrun_cli("-m", "app=halfar", "app.constants.A=1e-16,1e-17", *short, "hydra.sweep.dir=outputs/sweeps/A")
    assert done.returncode == 0, done.stderr
    assert "sweep of 2 jobs (0 not ok)" in done.stderr + done.stdout
    table = pd.read_csv(tmp_path / "outputs" / "sweeps" / "A" / "metrics.csv")
    assert list(table["app.constants.A"]) == [1e-16, 1e-17] and list(table["status"]) == ["ok", "ok"]
    assert table["max_error_m"].nunique() == 2  # A reached Γ: the dome flows ten times slower
    done = decrun_cli("app=halfar", "app.constants.A=1e-17", *short)
    assert done.returncode == 0, done.stderr
    (metrics,) = (tmp_path / "outputs" / "runs").glob("*/metrics.json")
    single = json.loads(metrics.read_text())
    assert single["max_error_m"] == pytest.approx(float(table["max_error_m"][1]), rel=1e-9)
    config = OmegaConf.load(metrics.parent / ".hydra" / "config.yaml")
    assert config.app.constants.A == 1e-17 and "A" not in config.app.parts.glen_law
