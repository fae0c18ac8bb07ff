"""Every ``decrun`` example in README.md, the docs pages (docs/**/*.md) and the comments of conf/ runs.

The examples are extracted from the text (code blocks and backticked spans of the pages, conf
comment lines), not copied here, so an example that is edited or added is tested as it
reads. Single runs go through the same composition as ``decrun`` (in process, fast);
sweeps (``-m``) and ``decrun-table`` run the real commands, those of the default app in the
default suite and the rest marked slow (:func:`cheap`).

Placeholders are replaced by real values (:data:`PLACEHOLDERS`); a line that only shows
syntax (``decrun -v ...``) is not an example and is listed in :data:`SYNTAX`.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment, write
from decrun.runner.mesh.sources.files import SAMPLE_MESHES, sample_mesh_dir

ROOT = Path(__file__).resolve().parents[3]
COMMAND = re.compile(r"^(?:\.venv/bin/)?(?:decrun(?:-table)?|python -m decrun)(?=\s|$)")
#: placeholders in examples → what the test substitutes
PLACEHOLDERS = {"/data/dragon.ply": str(sample_mesh_dir() / SAMPLE_MESHES["cow"])}
#: lines that show syntax, not a command to run
SYNTAX = ("decrun -v ...", "python -m decrun ...", "decrun-table", "decrun-table A [B …]",
          # docs/tracking.md's prose: a single run and a sweep of any options
          "decrun ... tracker=mlflow", "decrun -m", "decrun -m ... hydra.searchpath=[file://my_conf] tracker=wandb",
          "decrun -m key=a,b ...",
          # docs/running.md, docs/outputs-and-sweeps.md: the forms of --plot and --compare (examples next to them run)
          "decrun-table SWEEP --plot METRIC --x KEY", "decrun-table A [B …] --plot METRIC --x KEY [-o FILE]",
          "decrun-table --compare RUN_A RUN_B")
#: examples of bad input: they must fail with this message
EXPECTED_ERRORS = {"decrun +foo=1": "unknown root key",
                   # docs/apps/writing.md: a refusal in check, naming the step that works
                   "decrun app.scheme=explicit app.critical_dt=false": "leaves no critical step for app.dt_factor"}
#: commands an example needs to have run first (in the same directory)
PREREQUISITES = {
    "hydra.sweeper.resume=true": ["-m", "app.dt=0.001,0.002", "hydra.sweep.dir=outputs/sweeps/dt"],
    "outputs/sweeps/A outputs/sweeps/B": ["-m", "app.steps=1,2", "hydra.sweep.dir=outputs/sweeps/A"],
    "outputs/runs --metrics content_sha256": ["mesh.subdiv=1", "figures=false"],  # a single run to compare
    "--compare outputs/sweeps/A/0": ["-m", "app.steps=1,2", "hydra.sweep.dir=outputs/sweeps/A"],
    # the tutorial's table (docs/tutorial.md) reads the tutorial's sweep
    "outputs/sweeps/first --metrics": ["-m", "app.scheme=explicit,implicit", "app.dt_unit=critical",
                                       "app.dt_factor=0.5,1.5", "mesh.subdiv=2", "app.steps=40", "figures=false",
                                       "hydra.sweep.dir=outputs/sweeps/first"],
}
PREREQUISITES_B = ["-m", "app.steps=1,2", "hydra.sweep.dir=outputs/sweeps/B"]
#: pages whose commands another test runs as written: page → that test
RUN_ELSEWHERE = {
    "docs/models.md": "tests/test_model_docs.py (the walk-throughs and the refusals with their outputs; every other "
                      "command: test_every_other_command_of_the_page_runs)",
    "docs/gallery.md": "tests/test_numbers.py (every gallery command is a run of scripts/doc_numbers.py)",
    # its sweeps write into one MLflow store in order (a resume, then decrun-track of the same sweep)
    "docs/tracking.md": "tests/runner/results/test_tracker.py (test_the_docs_commands_run; the UI: test_tracker_ui.py)",
}


def pages() -> list[Path]:
    """README.md and every docs page whose commands this file runs."""
    found = [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))
    return [p for p in found if str(p.relative_to(ROOT)) not in RUN_ELSEWHERE]


def without_comment(line: str) -> str:
    """``line`` up to its shell comment (an unquoted ``#`` after a space: ``# Hydra's …`` is
    not a quote to close), stripped."""
    quote = None
    for i, char in enumerate(line):
        if quote:
            quote = None if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i].strip()
    return line.strip()


def refusals_in(text: str) -> dict[str, re.Pattern]:
    """The examples a page shows refused, ``(`decrun …` → `error: …`)``: command → a pattern of
    the documented line (``…`` stands for anything, a line break in the span for a space)."""
    found = {}
    for command, error in re.findall(r"`(decrun[^`]*)` → `(error: [^`]*)`", text):
        parts = [re.escape(" ".join(part.split())) for part in error.split("…")]
        found[command] = re.compile(".*?".join(parts).replace(r"\ ", r"\s+"), re.S)
    return found


def _commands_in(text: str) -> list[str]:
    found = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            command = without_comment(line)
            if COMMAND.match(command) and "pip install" not in command:
                found.append(command)
    for span in re.findall(r"(?<!`)`([^`\n]+)`(?!`)", text):
        if COMMAND.match(span.strip()):
            found.append(span.strip())
    return found


def examples() -> list[tuple[str, str]]:
    """(where, command) of every example in README.md, the docs pages and conf/**/*.yaml comments."""
    found = []
    for page in pages():
        text = page.read_text(encoding="utf-8")
        # the laptop-to-cluster block needs SLURM and a Ray cluster: tests/runner/sweep/test_laptop_to_cluster.py
        text = re.sub(r"<!-- laptop-to-cluster -->.*?<!-- /laptop-to-cluster -->", "", text, flags=re.S)
        found += [(str(page.relative_to(ROOT)), c) for c in _commands_in(text)]
    for path in sorted((ROOT / "conf").rglob("*.yaml")):
        where = str(path.relative_to(ROOT))
        for line in path.read_text().splitlines():
            comment = line.split("#", 1)[1] if "#" in line else ""
            match = re.match(r"\s+(decrun\s.*)$", comment)
            if match:  # a description may follow the command after two or more spaces
                found.append((where, re.split(r"\s{2,}", match.group(1).strip())[0]))
            found += [(where, c) for c in _commands_in(comment)]
            example = re.search(r"Example: ((?:[\w.+/]+=\S+ ?)+)", comment)
            if example:
                found.append((where, "decrun " + example.group(1).strip()))
    unique = {}
    for where, command in found:
        if command not in SYNTAX:
            unique.setdefault(command, where)
    return [(where, command) for command, where in unique.items()]


EXAMPLES = examples()
#: sweeps a page shows refused before anything runs: command → the documented line's pattern
REFUSED = {command: pattern for page in pages() for command, pattern in refusals_in(page.read_text()).items()}
SINGLE = [(w, c) for w, c in EXAMPLES if " -m " not in f"{c} " and not c.startswith("decrun-table")]
SWEEPS = [(w, c) for w, c in EXAMPLES if (w, c) not in SINGLE]


def cheap(command: str) -> bool:
    """A sweep of the default app, or a table of one: a few jobs of seconds each, run in the
    default suite. A thesis experiment, another app, launcher or sweeper: ``-m slow``."""
    return not any(word.startswith(("+experiment=", "app=", "hydra/launcher=", "hydra/sweeper="))
                   for word in command.split())


def arguments(command: str, tmp_path: Path) -> list[str]:
    for placeholder, value in PLACEHOLDERS.items():
        command = command.replace(placeholder, value)
    words = shlex.split(command)
    return words[2:] if words[0] == "python" else words[1:]


def test_the_examples_are_found():
    """The extraction sees the examples it must (a broken regex would test nothing)."""
    commands = [c for _, c in EXAMPLES]
    assert "decrun mesh=torus mesh.noise=0.2 app.dt_factor=0.3 app.steps=3" in commands
    assert any("app=vector_field mesh=planar" in c for c in commands)
    assert any("+experiment=fig6_9_square" in c for c in commands)
    assert len(SINGLE) >= 10 and len(SWEEPS) >= 9


@pytest.mark.parametrize("where, command", SINGLE, ids=[c for _, c in SINGLE])
def test_single_run_example_runs(where, command, tmp_path, decrun_cli):
    args = arguments(command, tmp_path)
    if "--cfg" in args or "--help" in args:  # prints the config, runs nothing: the real command
        done = decrun_cli(*args)
        assert done.returncode == 0 and "mesh:" in done.stdout, done.stderr
        return
    if command in EXPECTED_ERRORS:
        from decrun.errors import DecrunError

        with pytest.raises(DecrunError, match=EXPECTED_ERRORS[command]):
            run_experiment(compose_config(args))
        return
    if any("outputs/runs/<stamp>/result.h5" in a for a in args):  # a previous run's result
        write(run_experiment(compose_config(["app=hodge"])), tmp_path)
        args = [a.replace("outputs/runs/<stamp>/result.h5", str(tmp_path / "result.h5")) for a in args]
    assert "<" not in " ".join(args), f"{where}: unresolved placeholder in {command!r}"
    cfg = compose_config(args)
    out = tmp_path / "run"
    out.mkdir()
    done = run_experiment(cfg, out=out)
    written = write(done)  # the figures too
    result = done.result
    assert result.metrics.get("status") == "ok", (where, command, result.metrics)
    assert (out / "result.h5").is_file()
    drawn = any(p.suffix == ".png" for p in written)
    assert drawn == ("figures=false" not in args), (where, command, written)  # figures unless turned off


@pytest.mark.parametrize("where, command", [
    pytest.param(w, c, id=c, marks=[] if cheap(c) else [pytest.mark.slow]) for w, c in SWEEPS])
def test_sweep_example_runs(where, command, tmp_path):
    """The real command in a scratch directory; ``decrun-table`` runs on a sweep made first; a
    sweep the page shows refused ends with its documented line. Cheap ones (:func:`cheap`) run
    in the default suite."""
    args = arguments(command, tmp_path)
    env_python = [sys.executable, "-m", "decrun"]
    if any(a.startswith("hydra/launcher=slurm") for a in args):
        pytest.skip("needs a SLURM cluster (sbatch); the launcher config's composition is tested in test_sweeps")
    if any(a.startswith("hydra/sweeper=dt_crit_search") for a in args):
        pytest.importorskip("hydra_plugins.hydra_optuna_sweeper")
    for marker, needed in PREREQUISITES.items():
        if marker in command:
            for prerequisite in [needed] + ([PREREQUISITES_B] if "outputs/sweeps/B" in command else []):
                done = subprocess.run([*env_python, *prerequisite], cwd=tmp_path, capture_output=True, text=True)
                assert done.returncode == 0, done.stderr[-2000:]
    if command.startswith("decrun-table") and "<stamp>" not in command:
        done = subprocess.run([sys.executable, "-c", "import sys; from decrun.runner.command.table import table_main; "
                               "sys.exit(table_main(sys.argv[1:]))", *args], cwd=tmp_path, capture_output=True,
                              text=True)
        assert done.returncode == 0 and ("| " in done.stdout or "--plot" in args and "wrote" in done.stdout), done.stderr
        return
    if command.startswith("decrun-table"):
        sweep = subprocess.run([*env_python, "-m", "app.steps=1,2"], cwd=tmp_path, capture_output=True, text=True)
        assert sweep.returncode == 0, sweep.stderr
        stamp = next((tmp_path / "outputs" / "sweeps").iterdir()).name
        args = [a.replace("<stamp>", stamp) for a in args]
        done = subprocess.run([sys.executable, "-c", "import sys; from decrun.runner.command.table import table_main; "
                               "sys.exit(table_main(sys.argv[1:]))", *args], cwd=tmp_path, capture_output=True,
                              text=True)
        assert done.returncode == 0 and "| job |" in done.stdout, done.stderr
        return
    if any(a.startswith("hydra/launcher=joblib") for a in args):
        pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    done = subprocess.run([*env_python, *args], cwd=tmp_path, capture_output=True, text=True, timeout=1800)
    if command in REFUSED:  # refused as the page says, before any job ran
        assert done.returncode == 1 and REFUSED[command].search(" ".join(done.stderr.split())), done.stderr[-2000:]
        assert not (tmp_path / "outputs").exists() or not list((tmp_path / "outputs").rglob("result.h5"))
        return
    if "+experiment=operator_variants" in args:  # refusals are part of that table, each with its reason
        import pandas as pd

        table = pd.read_csv(next((tmp_path / "outputs" / "sweeps").iterdir()) / "metrics.csv")
        refused = table[table["status"] != "ok"]
        assert len(table) == 50 and len(refused) < len(table)
        assert refused["error"].str.contains("`").all(), refused["error"].tolist()  # a backticked override
        return
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert re.search(r"\(0 (failed|not ok)\)", done.stdout), done.stdout[-500:]
