"""docs/models.md and the "Declarative models" section of docs/apps/index.md say what the code does:

- the operator table in docs/models.md is the one ``reference_table()`` generates
  (``scripts/model_reference.py`` writes it);
- the "Your first model" walk-through runs as written: its YAML blocks are written to the files
  their first line names, its ``decrun``/``decrun-table`` commands and Python blocks run in a
  temporary directory in order, and each ``text`` block that follows one is its output (every
  line found in it; numbers within 2 %, ``…`` stands for anything);
- that section's three example commands run;
- every other command of docs/models.md (the opening block, backticked spans, ``$ decrun …``
  transcripts) runs: a refusal ends with the line the page shows, a run or sweep succeeds (the
  sweeps with -m slow); its YAML excerpts are lines of a shipped model's config.
"""

from __future__ import annotations

import importlib.util
import math
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "models.md"
APPS_PAGE = ROOT / "docs" / "apps" / "index.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
TABLE = "import sys; from decrun.runner.command.table import table_main; sys.exit(table_main())"


def reference_script():
    spec = importlib.util.spec_from_file_location("model_reference", ROOT / "scripts" / "model_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def section(text: str, title: str) -> str:
    """The markdown from the heading ``title`` to the next heading of the same level."""
    match = re.search(rf"^(#+) {re.escape(title)}\n", text, re.M)
    assert match, f"no section {title!r}"
    level = match.group(1)
    rest = text[match.end():]
    end = re.search(rf"^{level} ", rest, re.M)
    return rest[: end.start()] if end else rest


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block, in order."""
    return [(m.group(1), m.group(2)) for m in FENCE.finditer(text)]


def commands(body: str) -> list[list[str]]:
    """The command lines of a bash block (comments dropped), each as argv for this Python."""
    out = []
    for line in body.splitlines():
        words = shlex.split(line, comments=True)
        if not words:
            continue
        if words[0] == "decrun":
            out.append([sys.executable, "-m", "decrun", *words[1:]])
        elif words[0] == "decrun-table":
            out.append([sys.executable, "-c", TABLE, *words[1:]])
        else:
            raise AssertionError(f"the walk-through runs decrun and decrun-table only, got {line!r}")
    return out


def run(argv: list[str], cwd: Path, fails: bool = False) -> str:
    """The output (stdout then stderr) of ``argv``, which must succeed (or fail, ``fails``)."""
    paths = [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join(paths))
    done = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, timeout=600, env=env)
    output = done.stdout + done.stderr
    assert (done.returncode != 0) == fails, f"{' '.join(argv[2:])} exited {done.returncode}:\n{output[-3000:]}"
    return output


def line_matches(expected: str, actual: str, rtol: float = 0.02) -> bool:
    """``actual`` has ``expected``'s words, ``…`` matching anything and numbers within ``rtol``."""
    pattern, numbers = "", []
    for piece in re.split(r"(…)", expected.strip()):
        if piece == "…":
            pattern += ".*?"
            continue
        position = 0
        for match in NUMBER.finditer(piece):
            pattern += re.escape(piece[position:match.start()]) + f"({NUMBER.pattern})"
            numbers.append(float(match.group()))
            position = match.end()
        pattern += re.escape(piece[position:])
    found = re.search(pattern, actual)
    if not found:
        return False
    return all(math.isclose(float(value), number, rel_tol=rtol, abs_tol=1e-12)
               for value, number in zip(found.groups(), numbers, strict=True))


def check_output(expected: str, output: str, what: str) -> None:
    lines = output.splitlines()
    for line in expected.strip().splitlines():
        assert any(line_matches(line, actual) for actual in lines), \
            f"{what}: the documented line\n  {line}\nis not in the output:\n{output[-3000:]}"


def test_the_operator_table_is_the_generated_one():
    text = PAGE.read_text(encoding="utf-8")
    script = reference_script()
    from decrun.methods.model.operators import OPERATORS, reference_table

    committed = script.committed_table(text)
    assert committed == script.generated_table(), \
        "docs/models.md's operator table is stale: run python scripts/model_reference.py"
    assert committed == reference_table()
    assert script.render(text) == text
    for row in committed.splitlines():  # every row has exactly its three columns in markdown
        assert len(re.findall(r"(?<!\\)\|", row)) == 4, row
    for name in OPERATORS:
        assert f"| `{name}` |" in text


def test_the_checker_sees_a_stale_table():
    text = PAGE.read_text(encoding="utf-8")
    script = reference_script()
    stale = text.replace("| `laplacian` |", "| `laplacian_old` |", 1)
    assert script.render(stale) == text
    assert script.committed_table(stale) != script.generated_table()


def test_line_matching():
    assert line_matches("metrics: amplitude=0.2744, exact=0.2725, …", "metrics: amplitude=0.27441, exact=0.2725, x=1")
    assert not line_matches("metrics: amplitude=0.2744, …", "metrics: amplitude=0.30, x=1")
    assert line_matches("| 0 | 0 | ok | 0.3033 |", "| 0 | 0 | ok | 0.3033 |")
    assert not line_matches("| 0 | 0 | ok |", "| 0 | 0 | failed |")


def test_the_first_model_walkthrough_runs_as_written(tmp_path):
    steps = blocks(section(PAGE.read_text(encoding="utf-8"), "Your first model"))
    kinds = [language for language, _ in steps]
    assert kinds.count("yaml") >= 1 and kinds.count("bash") >= 2 and kinds.count("text") >= 2, kinds
    output = None
    checked = 0
    for language, body in steps:
        if language == "yaml":
            first = body.splitlines()[0]
            assert first.startswith("# "), f"a walk-through YAML block starts with '# <path>', got {first!r}"
            path = tmp_path / first[2:].strip()
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body)
            output = None
        elif language == "bash":
            output = "".join(run(argv, tmp_path) for argv in commands(body))
        elif language == "python":
            output = run([sys.executable, "-c", body], tmp_path)
        elif language == "text":
            assert output is not None, "a text block follows a command or a Python block"
            check_output(body, output, "walk-through")
            checked += 1
    assert checked >= 3
    assert (tmp_path / "outputs" / "sweeps" / "damping" / "metrics.csv").is_file()


def test_the_composed_model_example_runs_as_written(tmp_path):
    """The "Composed models" section: its part and model files written where their first line
    says, its commands run in order (the refusals fail), each text block their output's lines."""
    steps = blocks(section(PAGE.read_text(encoding="utf-8"), "Composed models"))
    assert [language for language, _ in steps] == ["yaml"] * 3 + ["bash", "text"] * 2
    outputs = []
    for language, body in steps:
        if language == "yaml":
            path = tmp_path / body.splitlines()[0][2:].strip()
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body)
        elif language == "bash":
            argvs = commands(body)
            refused = len(outputs) == 1  # the first block runs, the second is refused
            outputs.append("".join(run(argv, tmp_path, fails=refused) for argv in argvs))
            assert not refused or not (tmp_path / "outputs" / "runs").exists() or \
                len(list((tmp_path / "outputs" / "runs").glob("*/result.h5"))) == 1  # the refusals wrote nothing
        else:
            check_output(body, outputs[-1], "composed models")
    assert (tmp_path / "outputs" / "sweeps" / "decay" / "metrics.csv").is_file()


def test_the_applications_page_section_links_the_docs_and_its_commands_run(tmp_path):
    text = section(APPS_PAGE.read_text(encoding="utf-8"), "Declarative models (`app=heat`, your own `app=<model>`)")
    assert "(../models.md)" in text
    assert len(text.strip().splitlines()) <= 25
    bash = [body for language, body in blocks(text) if language == "bash"]
    assert len(bash) == 1
    argvs = commands(bash[0])
    assert len(argvs) == 3
    for argv in argvs:
        output = run(argv, tmp_path)
        assert "stable=True" in output, output[-2000:]
        if "-m" in argv[3:]:
            assert "(0 not ok)" in output, output[-2000:]


def test_the_bad_input_commands_end_with_the_documented_lines(tmp_path):
    steps = blocks(section(PAGE.read_text(encoding="utf-8"), "Bad input"))
    assert [language for language, _ in steps] == ["bash", "text"]
    argvs, expected = commands(steps[0][1]), steps[1][1].strip().splitlines()
    assert len(argvs) == len(expected) >= 5
    for argv, line in zip(argvs, expected, strict=True):
        output = run(argv, tmp_path, fails=True)
        last = output.strip().splitlines()[-1]
        assert last == line, f"{' '.join(argv[3:])}:\n  documented {line}\n  got        {last}"
        assert not (tmp_path / "outputs" / "runs").exists() or not any((tmp_path / "outputs" / "runs").glob(
            "*/result.h5")), "a refused model wrote a result"


def shipped_models() -> list[str]:
    """The model configs of conf/app (those whose _target_ is the model app; not _model.yaml,
    the options' defaults every model starts from)."""
    return sorted(path.stem for path in (ROOT / "conf" / "app").glob("*.yaml")
                  if not path.stem.startswith("_")
                  and "_target_: decrun.apps.model.Model" in path.read_text(encoding="utf-8"))


def test_every_shipped_model_is_in_the_docs():
    names = shipped_models()
    assert {"heat", "poisson", "wave", "heat_geodesics", "mcf"} <= set(names)
    rows = section(PAGE.read_text(encoding="utf-8"), "Shipped models")
    missing = [name for name in names if f"| `{name}`" not in rows]
    assert not missing, (f"conf/app/{missing[0]}.yaml is a model: give it a row in docs/models.md, 'Shipped models' "
                         "(its equations, exact answer and measured numbers)")


#: the page's prose names the commands themselves (not an example to run)
PROSE = ("decrun", "decrun-table")
#: the sections whose commands the tests above run as a whole, in order, with their outputs
WHOLE_SECTIONS = ("Your first model", "Composed models", "Bad input", "Your own operators")


def heavy(command: str) -> bool:
    """The page's sweeps are too heavy for the default suite (run with -m slow): 3 to 9 jobs of
    models up to 10k vertices (heat to mesh.subdiv=5, the Halfar dome at 1 km: 200
    factorizations of a 6k-vertex system, the Darcy refinements up to the finest box)."""
    return "-m" in shlex.split(command)


def page_commands(text: str) -> list[tuple[str, str | None]]:
    """(command, the error line it must end with, or None: it must succeed) of every command on
    docs/models.md — bash lines, backticked spans and ``$ decrun …`` lines of text blocks (the
    line after one is its output) — except those :data:`WHOLE_SECTIONS` run, and :data:`PROSE`."""
    done = {shlex.join(shlex.split(line, comments=True))
            for title in WHOLE_SECTIONS for language, body in blocks(section(text, title)) if language == "bash"
            for line in body.splitlines() if shlex.split(line, comments=True)}
    found: dict[str, str | None] = {}
    for language, body in blocks(text):
        lines = body.splitlines()
        if language == "bash":
            for line in lines:
                if shlex.split(line, comments=True):
                    found.setdefault(shlex.join(shlex.split(line, comments=True)), None)
        elif language == "text":
            for line, after in zip(lines, lines[1:] + [""], strict=True):
                if line.startswith("$ decrun"):
                    found[shlex.join(shlex.split(line[2:]))] = after if after.startswith("error:") else None
    prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    for span in re.findall(r"(?<!`)`([^`\n]+)`(?!`)", prose):
        if re.match(r"decrun(-table)?(\s|$)", span) and span not in PROSE:
            found.setdefault(shlex.join(shlex.split(span)), None)
    return [(command, error) for command, error in found.items() if command not in done]


PAGE_COMMANDS = page_commands(PAGE.read_text(encoding="utf-8"))


def test_the_page_commands_are_found():
    """Every command of the page outside the walk-throughs is seen (a broken extraction would test nothing)."""
    commands_ = dict(PAGE_COMMANDS)
    assert "decrun app=poisson" in commands_ and "decrun -m +experiment=cism_halfar" in commands_
    assert commands_["decrun app=halfar app.constants.n=0.5"].startswith("error: app.constants.n=0.5")
    assert len(commands_) >= 8 and not [c for c in commands_ if not c.startswith("decrun")]


@pytest.mark.parametrize("command, error", [
    pytest.param(command, error, id=command,
                 marks=[pytest.mark.slow] if heavy(command) else [])
    for command, error in PAGE_COMMANDS])
def test_every_other_command_of_the_page_runs(command, error, tmp_path):
    """The real command in a scratch directory (the walk-through's files written first when it
    uses them): a refusal ends with the line the page shows; a run or a sweep succeeds, every job ok."""
    words = shlex.split(command)
    if "hydra.searchpath=[file://my_conf]" in words:  # the walk-through's model: its YAML block
        (model,) = [body for language, body in blocks(section(PAGE.read_text(encoding="utf-8"), "Your first model"))
                    if language == "yaml"]
        path = tmp_path / model.splitlines()[0][2:].strip()
        path.parent.mkdir(parents=True)
        path.write_text(model)
    argv = [sys.executable, "-m", "decrun", *words[1:]] if words[0] == "decrun" else \
        [sys.executable, "-c", TABLE, *words[1:]]
    output = run(argv, tmp_path, fails=error is not None)
    if error is not None:
        assert output.strip().splitlines()[-1] == error, output[-3000:]
    elif "-m" in words:
        assert re.search(r"\(0 (failed|not ok)\)", output), output[-2000:]
    else:
        assert len(list((tmp_path / "outputs" / "runs").glob("*/result.h5"))) == 1, output[-2000:]


def _uncommented(line: str) -> str:
    """A YAML line without its trailing comment and outer spaces (no ``#`` inside quotes here)."""
    return line.split(" #", 1)[0].strip() if not line.lstrip().startswith("#") else ""


def excerpt_blocks(text: str) -> list[str]:
    """The page's YAML blocks that show part of a shipped model (not a file of the walk-throughs,
    which start with ``# <path>``)."""
    return [body for language, body in blocks(text) if language == "yaml" and not body.startswith("# ")]


def test_the_yaml_excerpts_are_lines_of_a_shipped_model():
    """Each excerpt's lines (comments aside) are lines of one conf/app/<model>.yaml, in order."""
    excerpts = excerpt_blocks(PAGE.read_text(encoding="utf-8"))
    assert len(excerpts) >= 2
    configs = {path.stem: [_uncommented(line) for line in path.read_text(encoding="utf-8").splitlines()]
               for path in sorted((ROOT / "conf" / "app").glob("*.yaml"))}
    for body in excerpts:
        wanted = [_uncommented(line) for line in body.splitlines() if _uncommented(line)]
        holders = [name for name, lines in configs.items()
                   if all(line in lines for line in wanted)
                   and [lines.index(line) for line in wanted] == sorted(lines.index(line) for line in wanted)]
        assert holders, f"docs/models.md: this YAML is not (part of) a shipped model in conf/app:\n{body}"


def _bad_input_lines(text: str) -> dict[str, str]:
    """The Bad input section's command → the last line it ends with (its test compares them)."""
    steps = blocks(section(text, "Bad input"))
    commands_ = [shlex.join(shlex.split(line, comments=True)) for line in steps[0][1].splitlines()
                 if shlex.split(line, comments=True)]
    return dict(zip(commands_, steps[1][1].strip().splitlines(), strict=True))


def command_output_blocks(text: str) -> list[str]:
    """The page's text blocks outside the walk-throughs that show a command's output: a
    transcript (``$ decrun …`` lines, each followed by its error line) or error lines a Bad input
    command ends with."""
    bad = set(_bad_input_lines(text).values())
    found = []
    for language, body in blocks(text):
        lines = body.strip().splitlines()
        if language != "text" or not lines:
            continue
        transcript = lines[0].startswith("$ decrun") and all(line.startswith(("$ decrun", "error:")) for line in lines)
        if transcript or all(line in bad for line in lines):
            found.append(body)
    return found


def test_the_transcripts_are_what_the_commands_print():
    """Each ``$ decrun …`` line's next line is the error its command ends with, as run by
    test_every_other_command_of_the_page_runs or the Bad input test."""
    text = PAGE.read_text(encoding="utf-8")
    expected = {**_bad_input_lines(text), **{c: e for c, e in PAGE_COMMANDS if e is not None}}
    pairs = 0
    for body in command_output_blocks(text):
        lines = body.strip().splitlines()
        for line, after in zip(lines, lines[1:], strict=False):
            if line.startswith("$ decrun"):
                assert expected.get(shlex.join(shlex.split(line[2:]))) == after, (line, after)
                pairs += 1
    assert pairs >= 2
