"""A typo in a config-group choice or a root value is one line naming the override, the
closest option and every option — not Hydra's listing with the machine's search path — and
the suggested override runs."""

from __future__ import annotations

import pytest

from cli_processes import decrun

TYPOS = [  # (override, the suggestion, a word of the option list)
    ("mesh=icosahedron", "mesh=icosphere", "torus"),
    ("app=smooth", "app=smoothing", "heat"),
    ("operator=whitny", "operator=whitney", "mixed_area"),
    ("export=vtk", "export=vtu", "xdmf"),
    ("solver=cholesky", "solver=cholmod", "direct"),
    ("hydra/launcher=nonexistent", None, "basic"),
    ("+experiment=fig5_8", "+experiment=fig5_8_t_hole", "fig6_7_cube"),  # a group added with +: the hint keeps it
]


@pytest.mark.parametrize("override, suggestion, listed", TYPOS)
def test_a_group_typo_is_one_line_with_the_options(tmp_path, override, suggestion, listed):
    proc = decrun(override, "figures=false", cwd=tmp_path, timeout=120)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"error: {override}: no such option"), lines[0]
    assert listed in lines[0] and "_post_processing" not in lines[0] and "search path" not in proc.stderr
    if suggestion:
        assert f"did you mean `{suggestion}`?" in lines[0]


@pytest.mark.parametrize("typo", ["mesh=icosahedron", "solver=cholesky"])
def test_the_suggested_option_runs(tmp_path, typo):
    proc = decrun(typo, "figures=false", cwd=tmp_path, timeout=120)
    suggestion = proc.stderr.split("did you mean `")[1].split("`")[0]
    fixed = decrun(suggestion, "figures=false", "app.steps=1", cwd=tmp_path, timeout=300)
    assert fixed.returncode == 0, fixed.stderr


def test_a_bad_root_boolean_is_one_line_and_its_fix_runs(tmp_path):
    proc = decrun("progress=maybe", cwd=tmp_path, timeout=120)
    assert proc.returncode == 1
    assert proc.stderr.strip() == "error: progress=maybe: not a boolean; use `progress=true` or `progress=false`"
    fixed = decrun("progress=false", "figures=false", "app.steps=1", cwd=tmp_path, timeout=300)
    assert fixed.returncode == 0, fixed.stderr


def test_a_group_outside_the_defaults_without_plus_is_one_line_and_its_fix_runs(tmp_path):
    """``experiment=...`` (experiments are added with +): one line with the + form, not Hydra's
    two lines advising it; the named override runs."""
    proc = decrun("experiment=fig6_7_cube", "figures=false", cwd=tmp_path, timeout=120)
    assert proc.returncode == 1
    assert proc.stderr.strip() == ("error: experiment=fig6_7_cube: experiment is not in the config's defaults list, "
                                   "it is added with +; use `+experiment=fig6_7_cube`")
    fix = proc.stderr.split("use `")[1].split("`")[0]
    fixed = decrun(fix, "mesh.refine_iterations=1", "figures=false", cwd=tmp_path, timeout=300)
    assert fixed.returncode == 0, fixed.stderr
