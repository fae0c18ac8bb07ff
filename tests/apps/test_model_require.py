"""A constant that makes a model ill-posed (a negative diffusivity, Glen's n below 1, γ ≤ 0 in
Cahn–Hilliard) is refused before any mesh work: one line naming the constant, the part it comes
from, the requirement and where it was declared, with an override that satisfies it — which
the tests run. The requirements are the model language's whitelisted expressions, compared."""

from __future__ import annotations

import pytest

from decrun.apps.model import Model
from decrun.errors import ConfigError
from decrun.methods.model.language import ModelError
from decrun.methods.model.require import check_requirements, parse_requirement

#: (model, override, the whole error line, the hint's override)
REFUSED = [
    ("gray_scott", "app.constants.Du=-1e-5",
     "error: app.constants.Du=-1e-05 makes the model ill-posed: app.require[0] requires Du >= 0; "
     "use `app.constants.Du=1e-05`", "app.constants.Du=1e-05"),
    ("halfar", "app.constants.A=-1e-16",
     "error: app.constants.A=-1e-16 (part glen_law's) makes the model ill-posed: app.parts.glen_law.require[0] "
     "requires A > 0; use `app.constants.A=1e-16`", "app.constants.A=1e-16"),
    ("halfar", "app.constants.n=0.5",
     "error: app.constants.n=0.5 (part glen_law's) makes the model ill-posed: app.parts.halfar_dynamics.require[0] "
     "requires n >= 1; use `app.constants.n=1`", "app.constants.n=1"),
    ("cahn_hilliard", "app.constants.g=-0.005",
     "error: app.constants.g=-0.005 makes the model ill-posed: app.require[1] requires g > 0; "
     "use `app.constants.g=0.005`", "app.constants.g=0.005"),
    ("klausmeier", "app.constants.a=0.5",
     "error: app.constants.a=0.5, app.constants.m=0.45 make the model ill-posed: app.require[1] requires a >= 2*m; "
     "use `app.constants.a=2`", "app.constants.a=2"),
]
#: a few steps: the hint's run only has to start and finish
SHORT = {"gray_scott": ["app.steps=2"], "halfar": ["app.t_end=2"], "cahn_hilliard": ["app.steps=2"],
         "klausmeier": ["app.steps=2"]}


@pytest.mark.parametrize("name, override, line, hint", REFUSED)
def test_an_ill_posed_constant_is_one_line_and_its_hint_runs(decrun_cli, tmp_path, name, override, line, hint):
    done = decrun_cli(f"app={name}", override, "figures=false", *SHORT[name])
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [line]
    assert not list(tmp_path.rglob("result.h5*"))  # refused before any work
    fixed = decrun_cli(f"app={name}", override, hint, "figures=false", *SHORT[name])
    assert fixed.returncode == 0, fixed.stderr


def test_a_sweep_with_an_ill_posed_value_is_refused_before_its_first_job(decrun_cli, tmp_path):
    done = decrun_cli("-m", "app=heat", "app.constants.k=1,-1", "app.steps=2", "app.t_end=null", "figures=false")
    assert done.returncode == 1
    assert "app.constants.k=-1 makes the model ill-posed: app.require[0] requires k >= 0; use `app.constants.k=1`" in \
        done.stderr
    assert not list(tmp_path.rglob("result.h5*"))


@pytest.mark.parametrize("text, values, holds", [
    ("Du >= 0", {"Du": 0.0}, True), ("Du > 0", {"Du": 0.0}, False), ("a >= 2*m", {"a": 0.94, "m": 0.45}, True),
    ("a >= 2*m", {"a": 0.8, "m": 0.45}, False), ("sqrt(a**2 - 4*m**2) < a", {"a": 1.0, "m": 0.1}, True),
    ("n - 1 >= -0", {"n": 1.0}, True), ("max(A, B) <= 2", {"A": 1.0, "B": 3.0}, False),
    ("log(A) > 0", {"A": -1.0}, False),  # NaN fails every comparison
])
def test_a_requirement_compares_two_expressions_of_constants(text, values, holds):
    requirement = parse_requirement(text, "app.require[0]")
    if holds:
        check_requirements([requirement], values)
    else:
        with pytest.raises(ModelError, match=r"^app\.constants\..* the model ill-posed: app\.require\[0\] requires "):
            check_requirements([requirement], values)


@pytest.mark.parametrize("text, message", [
    ("Du", r"^app\.require\[0\]: a requirement is one comparison"),
    ("Du > 0 > 1", r"^app\.require\[0\]: a requirement is one comparison"),
    ("Du == 0", r"^app\.require\[0\]: a requirement is one comparison"),
    ("__import__('os') > 0", r"^app\.require\[0\]: "),
    ("Du.real > 0", r"^app\.require\[0\]: "),
])
def test_a_requirement_that_is_not_a_comparison_of_expressions_is_refused(text, message):
    with pytest.raises(ModelError, match=message):
        parse_requirement(text, "app.require[0]")


def test_a_requirement_reads_constants_only_and_is_checked_when_the_model_is_built():
    with pytest.raises(ConfigError, match=r"^app\.require\[0\]: 'u' is not a constant of the model; a requirement "
                                          r"reads constants, dt and numbers only"):
        Model(fields={"u": {"form": "0", "initial": "x"}}, equations=["dt(u) = k*laplacian(u)"],
              constants={"k": 1.0}, require=["u > 0"])
    with pytest.raises(ConfigError, match=r"^app\.dt=0\.01, app\.constants\.k=-2 make the model ill-posed: app\.require\[0\] "
                                          r"requires k\*dt >= 0; use `app\.constants\.k=2`$"):
        Model(fields={"u": {"form": "0", "initial": "x"}}, equations=["dt(u) = k*laplacian(u)"],
              constants={"k": -2.0}, require=["k*dt >= 0"])
