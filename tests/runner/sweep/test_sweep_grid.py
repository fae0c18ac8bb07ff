"""The decrun sweeper's grid (decrun.runner.sweep.grid, on Hydra's public override parser)
is Hydra's basic sweeper's: the same jobs in the same order for lists, ranges, globs,
quoted and plain values, repeated keys, ``+`` / ``~`` / ``++`` and ``hydra.sweeper.params``
before the command line (``BasicSweeper`` is in ``hydra._internal``: only this test
imports it)."""

from __future__ import annotations

import itertools

import pytest
from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser

from decrun.runner.job.progress import sweep_size
from decrun.runner.sweep.grid import grid

LINES = ["app.dt=0.1,0.2", "mesh.subdiv=2", "operator=circumcentric,barycentric", "seed=range(0,3)",
         "app.label='a,b',c", "+app.note=x,y", "~app.rescale", "++figures=false,true", "app.dt=0.3",
         "x=choice(1,2)", "s=range(1,2,0.5)", "q=[1,2]", "empty=''", "d={a:1}", "r=range(3)"]


def _basic(lines: list[str]) -> list[list[str]]:
    parsed = OverridesParser.create().parse_overrides(lines)
    return [job for batch in BasicSweeper.split_arguments(parsed, None) for job in batch]


def test_the_grid_is_the_basic_sweepers_jobs_in_its_order():
    parser = OverridesParser.create()
    cases = [[]] + [list(c) for n in (1, 2) for c in itertools.combinations(LINES, n)]
    for lines in cases + [list(c) for c in itertools.combinations(LINES, 3)][::9] + [LINES, LINES[::-1]]:
        assert grid(parser.parse_overrides(lines)) == _basic(lines), lines


def test_sweep_size_counts_the_grid_with_the_configs_params():
    assert sweep_size(["app.dt=0.1,0.2", "seed=range(3)"], {"mesh.subdiv": "2,3"}) == 12
    assert sweep_size(["app.dt=0.1,0.2"], {"app.dt": "1,2,3"}) == 2  # the command line's replaces the config's
    assert sweep_size(["app.dt=interval(0,1)"]) is None  # not a grid: a bar without a total


def test_a_sweep_that_is_not_a_grid_is_refused_naming_it():
    with pytest.raises(ValueError, match=r"app\.dt=interval\(0,1\): the decrun sweeper runs a grid"):
        grid(OverridesParser.create().parse_overrides(["app.dt=interval(0,1)"]))
