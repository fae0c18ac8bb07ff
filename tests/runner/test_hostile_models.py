"""Hostile model files through the real ``decrun`` command (issue 50, items 5, 6 and 10): plot
names that are paths or 100k characters long, YAML alias bombs in a model, a part or a file of
the search path, a Latin-1 byte, unreadable files and directories, part names that are paths,
and chains of definitions deeper than Python's stack. Each ends as one line naming the file or
key, never a traceback, a hang or a file outside the run directory."""

from __future__ import annotations

import ctypes
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from decrun.errors import CorruptFileError
from decrun.runner.io.config_files import MAX_ALIASED_NODES, aliased_nodes, check_aliases
from decrun.runner.results.checked import load_yaml

from cli_processes import decrun, env

SEARCH = "hydra.searchpath=[file://my_conf]"


def model(tmp_path: Path, name: str, text: str, group: str = "app") -> None:
    """``my_conf/<group>/<name>.yaml`` under ``tmp_path`` holding ``text``."""
    directory = tmp_path / "my_conf" / group
    directory.mkdir(parents=True, exist_ok=True)
    (directory / f"{name}.yaml").write_text(text, encoding="utf-8")


def one_line(proc: subprocess.CompletedProcess, *words: str) -> str:
    """The single stderr line of a refused command (exit 1), holding every one of ``words``."""
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr and len(lines[0]) < 400, lines[0][:400]
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


DARCY_PLOT = "defaults:\n  - darcy\n  - _self_\nmodel: {name}\nplots:\n  {key}: {{color: pressure, arrows: velocity}}\n"


@pytest.mark.parametrize("name", ["../../escaped", "{tmp}/outside/escaped", "sub/escaped"],
                         ids=["parent", "absolute", "separator"])
def test_a_plot_name_that_is_a_path_is_refused(tmp_path, name):
    work = tmp_path / "work"
    name = name.format(tmp=tmp_path)
    model(work, "plotted", DARCY_PLOT.format(name="plotted", key=f'"{name}"'))
    proc = decrun("app=plotted", SEARCH, "hydra.run.dir=deep/run", cwd=work, timeout=200)
    one_line(proc, "app.plots", name[:30], "never a path")  # a name over 40 characters is shown by its start
    assert not list(tmp_path.rglob("*.png"))  # neither in the run nor outside it (../../, the absolute path)


def test_a_plot_name_of_100k_characters_is_one_short_line(tmp_path):
    name = "a" * 100_000  # an explicit key: YAML's plain keys stop at 1024 characters
    model(tmp_path, "long", f"defaults:\n  - darcy\n  - _self_\nmodel: long\nplots:\n  ? {name}\n"
                            "  : {color: pressure, arrows: velocity}\n")
    proc = decrun("app=long", SEARCH, "hydra.run.dir=run", cwd=tmp_path, timeout=200)
    one_line(proc, "app.plots", "(100000 characters)", "longer than 100 characters")
    assert len(proc.stdout) + len(proc.stderr) < 1000


def test_a_plot_with_a_name_draws_its_figure(tmp_path):
    model(tmp_path, "plotted", DARCY_PLOT.format(name="plotted", key="flow_2"))
    proc = decrun("app=plotted", SEARCH, "hydra.run.dir=run", cwd=tmp_path, timeout=200)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (tmp_path / "run" / "flow_2.png").is_file()


def bomb(levels: int, width: int = 10) -> str:
    """YAML whose aliases stand for ``width ** levels`` scalars ("billion laughs")."""
    lines = ["bomb:\n", f"  l0: &l0 [{', '.join(['x'] * width)}]\n"]
    lines += [f"  l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * width)}]\n" for i in range(1, levels + 1)]
    return "".join(lines)


def test_alias_counting_is_exact_and_stops_at_the_limit():
    assert aliased_nodes("a: &a [1, 2, 3]\nb: *a\nc: [*a, *a]\n") == 3 * 4  # each alias: the list and 3 scalars
    assert aliased_nodes("a: &a {k: [1, 2]}\nb: *a\n") == 1 + 1 + 1 + 2  # mapping, key, list, 2 items
    assert aliased_nodes(bomb(2)) == 10 * 11 + 10 * 11 * 10 + 10  # l1: 10 × l0, l2: 10 × l1
    assert MAX_ALIASED_NODES < aliased_nodes(bomb(9)) <= 2 * MAX_ALIASED_NODES + 10 ** 4  # stops early
    check_aliases(bomb(2), "small.yaml")  # 1220 nodes: a config's own repetition
    with pytest.raises(CorruptFileError, match=r"big\.yaml: its YAML aliases .* more than 10000 nodes"):
        check_aliases(bomb(5), "big.yaml")


@pytest.mark.parametrize("where", ["model", "part", "own_group"])
def test_an_alias_bomb_in_a_config_file_is_refused_before_composing(tmp_path, where):
    # 10⁹ leaves: OmegaConf would build them for days; the refusal comes before Hydra reads the file
    if where == "model":
        model(tmp_path, "bombed", "defaults:\n  - heat\n  - _self_\nmodel: bombed\n" + bomb(9))
        args, culprit = ["app=bombed"], "my_conf/app/bombed.yaml"
    elif where == "part":
        model(tmp_path, "exploding", "parts:\n  exploding:\n    constants: {k: 1.0}\n" +
              bomb(9).replace("bomb:", "    extra:").replace("\n  l", "\n      l"), group="app/parts")
        args, culprit = ["app=halfar", "app/parts@app=[exploding]"], "my_conf/app/parts/exploding.yaml"
    else:
        model(tmp_path, "boom", bomb(9), group="mine")
        args, culprit = ["app=heat", "+mine=boom"], "my_conf/mine/boom.yaml"
    proc = decrun(*args, SEARCH, "hydra.run.dir=run", cwd=tmp_path, timeout=60)
    one_line(proc, culprit, "alias bomb", str(MAX_ALIASED_NODES))
    assert not (tmp_path / "run").exists()


def test_an_alias_bomb_in_a_file_decrun_reads_is_named(tmp_path):
    path = tmp_path / "overrides.yaml"
    path.write_text(bomb(9))
    with pytest.raises(CorruptFileError, match="overrides.yaml: its YAML aliases"):
        load_yaml(path)


def test_a_latin1_byte_in_a_comment_names_the_file_and_the_offset(tmp_path):
    model(tmp_path, "accented", "")
    text = "defaults:\n  - heat\n  - _self_\n# caf\xe9 au lait\nmodel: accented\n"
    (tmp_path / "my_conf" / "app" / "accented.yaml").write_bytes(text.encode("latin-1"))
    proc = decrun("app=accented", SEARCH, "hydra.run.dir=run", cwd=tmp_path, timeout=60)
    offset = text.encode("latin-1").index(b"\xe9")
    one_line(proc, "my_conf/app/accented.yaml", f"byte 0xe9 at offset {offset}", "not UTF-8", "save the file as UTF-8")


def _without_root_file_access() -> None:  # runs in the child between fork and exec
    """Drop CAP_DAC_OVERRIDE (1) and CAP_DAC_READ_SEARCH (2) from the bounding set: the child, root
    as the tests are, then obeys file modes as any user does (chmod 000 stops it)."""
    libc = ctypes.CDLL(None, use_errno=True)
    for capability in (1, 2):
        if libc.prctl(24, capability, 0, 0, 0) != 0:  # PR_CAPBSET_DROP
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP)")


def decrun_as_a_user(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``decrun *args`` in a child that file modes apply to, also when the tests run as root."""
    return subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=env(), capture_output=True, text=True,
                          timeout=120, preexec_fn=_without_root_file_access if os.geteuid() == 0 else None)


@pytest.mark.parametrize("unreadable", ["file", "directory"])
def test_an_unreadable_model_file_or_directory_says_it_cannot_be_read(tmp_path, unreadable):
    model(tmp_path, "closed", "defaults:\n  - heat\n  - _self_\nmodel: closed\n")
    path = tmp_path / "my_conf" / "app" / ("closed.yaml" if unreadable == "file" else "")
    path.chmod(0)
    try:
        proc = decrun_as_a_user("app=closed", SEARCH, "hydra.run.dir=run", cwd=tmp_path)
    finally:
        path.chmod(0o755)
    line = one_line(proc, f"cannot read the config {unreadable} {str(path).rstrip('/')}: Permission denied",
                    "make it readable (chmod u+r")
    assert "cannot write" not in line and "output directory" not in line


@pytest.mark.parametrize("parts, shown", [("[/etc/passwd]", "'/etc/passwd'"), ("['']", "''")],
                         ids=["absolute", "empty"])
def test_a_part_named_by_a_path_or_nothing_is_one_line(tmp_path, parts, shown):
    proc = decrun("app=halfar", f"app/parts@app={parts}", "hydra.run.dir=run", cwd=tmp_path, timeout=60)
    one_line(proc, "app=halfar", f"{shown} is not a part's name", "glen_law | halfar_dynamics")


def chain(length: int) -> str:
    equations = ", ".join(['"v1 = x"'] + [f'"v{i} = v{i - 1} + 1"' for i in range(2, length + 1)])
    return (f"defaults:\n  - _model\n  - _self_\nmodel: chain\nfields:\n  u: {{form: 0, initial: \"x\"}}\n"
            f"equations: [{equations}, \"dt(u) = -u\"]\ndt: 0.01\nsteps: 1\nmetrics:\n  chained: \"max(abs(v{length} - x - {length - 1}))\"\n")


def test_a_chain_of_definitions_beyond_the_limit_is_one_line(tmp_path):
    model(tmp_path, "chain", chain(1000))
    proc = decrun("app=chain", SEARCH, "hydra.run.dir=run", "figures=false", cwd=tmp_path, timeout=120)
    one_line(proc, "app.equations[300]", "v301 reads a chain of 301 definitions", "at most 300")


@pytest.mark.slow
def test_a_chain_of_definitions_at_the_limit_runs(tmp_path):
    model(tmp_path, "chain", chain(300))
    proc = decrun("app=chain", SEARCH, "hydra.run.dir=run", "figures=false", "mesh.subdiv=1", cwd=tmp_path, timeout=200)
    assert proc.returncode == 0, proc.stderr[-2000:]
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["chained"] < 1e-12  # v300 = x + 299, each link evaluated
