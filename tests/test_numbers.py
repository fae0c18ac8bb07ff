"""The numbers the docs show (docs/numbers.json, made by scripts/doc_numbers.py) are the code's.

Every run of the script's table is rerun here (``decrun <overrides> figures=false``, the same
composition and run as the command), every source function called, and every number taken from
it must equal the committed one within the tolerance the file states; a failure names the
number, the page placeholder and the run. Numbers no single run gives (the spectrum table, the
operator-variants sweep, mesh statistics, the models' convergence tables, the fluid's drift
table) come from a function (a ``Source``) and are checked the same way. Every run — smoothing,
parametrization, vector fields, Hodge, spectra, the operator variants, the models' convergence
and the Halfar dome, the fluid channels of Figs. 7.15–7.17 up to 12059 faces, the gallery's — and
the light sources are in the default suite; the sources the script marks ``slow`` (the fluid's
200-step inviscid channels and 1000-step unforced runs) run with ``-m slow``, which .ci/run runs
after the default suite, so CI checks every number. Also: the file holds exactly the numbers the script
declares, every placeholder of a page is in it, and every command the gallery shows is one of
the runs checked here.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("decrun_doc_numbers", ROOT / "scripts" / "doc_numbers.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


doc_numbers = _script()
RUNS = doc_numbers.all_runs()
NUMBERS = doc_numbers.load()


def test_the_file_holds_exactly_the_declared_numbers():
    declared = {f"{name}.{key}" for name, run in RUNS.items() for key in run.numbers}
    missing, extra = sorted(declared - set(NUMBERS)), sorted(set(NUMBERS) - declared)
    assert not missing, f"docs/numbers.json lacks {missing[:5]}: run python scripts/doc_numbers.py --only <run>"
    assert not extra, f"docs/numbers.json holds numbers no run declares: {extra[:5]}"
    for name, entry in NUMBERS.items():
        run = RUNS[name.rsplit(".", 1)[0]]
        made_by = doc_numbers.made_by(run)
        assert {key: entry.get(key) for key in made_by} == made_by, \
            f"{name}: made by another run than scripts/doc_numbers.py says"


def test_every_placeholder_of_the_pages_is_a_number():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    for page in pages:
        for name in re.findall(r"\{\{\s*numbers\.([\w.]+)\s*\}\}", page.read_text(encoding="utf-8")):
            assert name in NUMBERS, f"{page.relative_to(ROOT)}: {{{{ numbers.{name} }}}} is not in docs/numbers.json"


def test_every_gallery_command_is_a_checked_run():
    text = (ROOT / "docs" / "gallery.md").read_text(encoding="utf-8")
    shown = re.findall(r"^- `decrun ([^`]*)`", text, flags=re.M)
    runs = {" ".join(run.overrides) for run in RUNS.values() if isinstance(run, doc_numbers.Run)}
    assert shown and all(command in runs for command in shown), [c for c in shown if c not in runs]


def test_drift_names_what_moved_and_accepts_what_did_not():
    entry = {"value": 2945.08, "rtol": 1e-3, "atol": 0.0, "format": ".0f", "scale": 1.0}
    assert doc_numbers.drift(entry, 2945.5) is None
    assert "1370 instead of 2945.08" in doc_numbers.drift(entry, 1370.0)
    assert doc_numbers.drift({**entry, "value": True}, False) == "False instead of True"
    assert doc_numbers.drift({**entry, "value": 211}, 212) == "212 instead of 211"
    assert doc_numbers.render({**entry, "value": 0.25653, "format": ".4g"}) == "0.2565"
    assert doc_numbers.render({**entry, "value": 0.0130, "format": ".2f", "scale": 100.0}) == "1.30"


def test_a_source_is_recorded_and_checked_like_a_run():
    """A Source's entries name its function instead of overrides; its strings (a refusal's
    reason in the spectrum table) are held exactly, its numbers to their tolerance."""
    def cells():
        return {"cube": "zero ⋆", "sphere": 0.016422}

    source = doc_numbers.Source(cells, {"cube": doc_numbers.N("cube"), "sphere": doc_numbers.N("sphere", ".2e")})
    made = doc_numbers.entries("demo", source, doc_numbers.run_metrics(source))
    assert made["demo.sphere"]["source"] == "scripts/doc_numbers.py:cells" and "overrides" not in made["demo.sphere"]
    assert doc_numbers.render(made["demo.sphere"]) == "1.64e-02" and doc_numbers.render(made["demo.cube"]) == "zero ⋆"
    assert doc_numbers.drift(made["demo.cube"], "⋆ < 0") == "'⋆ < 0' instead of 'zero ⋆'"
    assert doc_numbers.drift(made["demo.sphere"], 0.0164225) is None and doc_numbers.drift(made["demo.sphere"], 0.0144)
    with pytest.raises(KeyError, match=r"`cells\(\)` of scripts/doc_numbers.py has no metric 'ball'"):
        doc_numbers.entries("demo", doc_numbers.Source(cells, {"ball": doc_numbers.N("ball")}), cells())


def test_a_source_entry_names_its_function_and_is_checked_like_a_run():
    source = doc_numbers.Source("scripts/fluid_numbers.py:wake", {"asym": doc_numbers.N("asymmetry_1400", rtol=0.1)})
    entry = doc_numbers.entries("s", source, {"asymmetry_1400": 0.005})["s.asym"]
    assert entry["source"] == "scripts/fluid_numbers.py:wake" and "overrides" not in entry
    assert doc_numbers.made_by(source) == {"source": "scripts/fluid_numbers.py:wake"}
    assert doc_numbers.drift(entry, 0.0054) is None and "0.006 instead of 0.005" in doc_numbers.drift(entry, 0.006)
    with pytest.raises(KeyError, match="scripts/fluid_numbers.py:wake has no metric 'asymmetry_1400'"):
        doc_numbers.entries("s", source, {})
    assert doc_numbers.source_function("scripts/fluid_numbers.py:wake").__name__ == "wake"


#: run → the runs whose numbers its metrics also give (itself and its aliases)
GROUPS: dict[str, list[str]] = {}
for _name in RUNS:
    GROUPS.setdefault(doc_numbers.ALIASES.get(_name, _name), []).append(_name)
CASES = [pytest.param(name, marks=[pytest.mark.slow] if RUNS[name].slow else [], id=name) for name in GROUPS]


def test_an_alias_composes_the_config_of_its_run():
    from omegaconf import OmegaConf

    from decrun.runner.job.config import compose_config

    for alias, source in doc_numbers.ALIASES.items():
        a, b = (OmegaConf.to_yaml(compose_config([*RUNS[n].overrides, "figures=false"])) for n in (alias, source))
        assert a == b, f"scripts/doc_numbers.py: {alias} is not the run {source}"


@pytest.mark.parametrize("name", CASES)
def test_a_rerun_gives_the_committed_numbers(name):
    metrics = doc_numbers.run_metrics(RUNS[name])
    moved = []
    for member in GROUPS[name]:
        run = RUNS[member]
        for key, number in run.numbers.items():
            entry = NUMBERS[f"{member}.{key}"]
            why = doc_numbers.drift(entry, metrics.get(number.metric))
            if why:
                moved.append(f"{{{{ numbers.{member}.{key} }}}} ({number.metric} of {run.describe()}): {why}")
    assert not moved, ("numbers shown in the docs moved beyond their tolerance — if on purpose, run "
                       f"python scripts/doc_numbers.py --only {name}:\n  " + "\n  ".join(moved))
