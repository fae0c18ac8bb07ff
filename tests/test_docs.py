"""The documentation site (mkdocs.yml, docs/) and the README.

- the site builds with ``mkdocs build --strict`` (warnings are errors: a broken link, a page
  outside the nav, a docstring mkdocstrings cannot read, a ``{{ numbers.… }}`` not in
  docs/numbers.json);
- every page under docs/ is in the nav (the test names the file), so a page added in another
  branch is noticed at merge;
- the built "Config groups" page lists every option of every conf/ group and every key of its
  YAML file, found here by walking conf/ independently of the generator;
- the README fits on a page, keeps the set-up commands CI reads, and links only pages that exist;
  no page cites files that are not in the repository or issue numbers;
- the tutorial's commands and Python block run in order, and every other Python block of the
  pages runs (the python-api block of running.md: tests/runner/test_api.py; docs/models.md:
  tests/test_model_docs.py);
- docs/cluster.md shows the shipped launcher config itself (included with ``--8<--``);
- every fenced block of README.md and the pages (every line of a ``bash`` block) is run by a
  named test or listed in :data:`NOT_RUN` with the reason (:func:`test_every_fenced_block_is_run_or_listed`).
"""

from __future__ import annotations

import html
import importlib.util
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.rglob("*.md"))
#: python blocks another test runs: page → that test
PYTHON_RUN_ELSEWHERE = {"running.md": "tests/runner/test_api.py", "models.md": "tests/test_model_docs.py",
                        "tutorial.md": "test_the_tutorial_runs_in_order (below)",
                        "extending.md": "tests/runner/config/test_extending.py (test_the_extending_pages_plugin_runs_as_written)"}
#: files the pages must not cite: they are not in the repository
NOT_IN_REPO = ("FLUIDS.md", "THESIS_NOTES.md", "MODELS.md", "DESIGN.md", "thesis.txt", "shared/")


def _nav_pages(nav) -> list[str]:
    found = []
    for item in nav:
        if isinstance(item, str):
            found.append(item)
        elif isinstance(item, dict):
            for value in item.values():
                found += _nav_pages(value) if isinstance(value, list) else [value]
    return found


def _mkdocs_config() -> dict:
    class Loader(yaml.SafeLoader):
        pass

    Loader.add_multi_constructor("!", lambda loader, suffix, node: None)  # mkdocs' !ENV etc.
    return yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=Loader)


def test_every_docs_page_is_in_the_nav():
    nav = set(_nav_pages(_mkdocs_config()["nav"]))
    for page in PAGES:
        name = str(page.relative_to(DOCS))
        assert name in nav, f"docs/{name} is not in the nav of mkdocs.yml: add it there"
    for name in nav:
        assert (DOCS / name).is_file(), f"mkdocs.yml's nav names docs/{name}, which does not exist"


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site built by ``mkdocs build --strict`` into a temporary directory."""
    pytest.importorskip("mkdocs", reason='pip install -e ".[docs]"')
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=1800,
                          env={**__import__("os").environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-5000:]
    return out


def _text(path: Path) -> str:
    """The visible text of a built page (tags dropped, entities decoded)."""
    raw = path.read_text(encoding="utf-8")
    raw = re.sub(r"<(script|style)\b.*?</\1>", " ", raw, flags=re.S)
    return html.unescape(re.sub(r"<[^>]+>", "", raw))


def test_the_site_builds_strict_and_fills_every_number(site):
    for page in PAGES:
        name = page.relative_to(DOCS)
        built = site / (("index.html" if name.stem == "index" else f"{name.stem}/index.html") if name.parent == Path(".")
                        else name.parent / ("index.html" if name.stem == "index" else f"{name.stem}/index.html"))
        assert built.is_file(), f"docs/{name}: no {built.relative_to(site)} in the built site"
        text = _text(built)
        left = re.search(r"\{\{\s*numbers\.[\w.]+\s*\}\}", text)
        assert not left and "<!-- config-options -->" not in text, f"docs/{name}: a placeholder left"


def test_the_fluid_page_shows_the_numbers_of_the_committed_runs(site):
    """A placeholder becomes the number of docs/numbers.json as the script prints it."""
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import doc_numbers
    finally:
        sys.path.remove(str(ROOT / "scripts"))
    numbers = doc_numbers.load()
    text = _text(site / "apps" / "fluid" / "index.html")
    entry = numbers["fig7_15_1400_0_005.enstrophy"]
    assert "at ν = 0.02" in text and doc_numbers.render(entry) in text


def conf_options() -> list[tuple[str, str, list[str]]]:
    """(group, option, top-level keys of its file) of every option file in conf/, walked here."""
    found = []
    for group in ("mesh", "operator", "boundary", "app", "solver", "export"):
        for path in sorted((ROOT / "conf" / group).rglob("*.yaml")):
            option = str(path.relative_to(ROOT / "conf" / group).with_suffix(""))
            if any(part.startswith("_") for part in Path(option).parts):
                continue
            data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
            keys = [k for k in data if k not in ("defaults", "_target_") and not str(k).startswith("#")]
            found.append((group, option, keys))
    return found


def test_the_config_page_lists_every_option_and_key(site):
    text = _text(site / "config" / "index.html")
    post = yaml.safe_load((ROOT / "conf" / "mesh" / "_post_processing.yaml").read_text(encoding="utf-8"))
    missing = []
    for group, option, keys in conf_options():
        if f"{group}={option}" not in text:
            missing.append(f"{group}={option} (conf/{group}/{option}.yaml)")
        missing += [f"{group}.{key} (conf/{group}/{option}.yaml)" for key in keys if f"{group}.{key}" not in text]
    missing += [f"mesh.{key} (conf/mesh/_post_processing.yaml)" for key in post if f"mesh.{key}" not in text]
    for path in sorted((ROOT / "conf" / "experiment").glob("*.yaml")):
        if f"+experiment={path.stem}" not in text:
            missing.append(f"+experiment={path.stem}")
    assert not missing, f"not on the Config groups page: {missing}"
    for name in ("bunny", "channel", "cow", "grid_holes", "icosphere_clean"):
        assert f"mesh={name}" in text
    assert "mesh.largest_component" in text


def test_the_readme_fits_on_a_page_and_keeps_the_set_up_commands():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250
    for marker in ("main-command", "test-command"):
        block = re.search(rf"<!-- {marker} -->\n```bash\n(.*?)\n```\n<!-- /{marker} -->", text, re.S)
        assert block, f"README.md: the {marker} block"
    main = re.search(r"<!-- main-command -->\n```bash\n(.*?)\n```", text, re.S).group(1)
    assert main.endswith(".venv/bin/decrun") and "pip install -e ." in main
    test = re.search(r"<!-- test-command -->\n```bash\n(.*?)\n```", text, re.S).group(1)
    assert test.endswith(".venv/bin/python -m pytest -n auto --maxprocesses=4")
    assert "measurements.md" in text  # every benchmark's record, beside the Speed section's summary
    speed = text.split("## Speed", 1)[1].split("\n## ", 1)[0]  # quiet-machine numbers: commit, command each
    assert re.search(r"at commit [0-9a-f]{7}", speed) and "load average" in speed
    rows = [line for line in speed.splitlines() if line.startswith("| ") and "benchmarks/" in line]
    assert len(rows) >= 5
    for row in rows:
        script = re.search(r"benchmarks/(\w+)\.py", row).group(0)
        assert (ROOT / script).is_file(), f"README.md's Speed section names {script}, which does not exist"
    for link in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text):
        if not link.startswith("http"):
            assert (ROOT / link).exists(), f"README.md links {link}, which does not exist"


@pytest.mark.parametrize("page", [ROOT / "README.md", *PAGES], ids=lambda p: str(p.relative_to(ROOT)))
def test_no_page_cites_a_file_outside_the_repository_or_an_issue(page):
    text = page.read_text(encoding="utf-8")
    for name in NOT_IN_REPO:
        assert name not in text, f"{page.relative_to(ROOT)} cites {name}, which is not in the repository"
    match = re.search(r"\bissues? \d+", text)
    assert not match, f"{page.relative_to(ROOT)}: {match.group(0)!r} — say what the code does, not its history"


def _blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", text, flags=re.S | re.M)


PYTHON_BLOCKS = [(page, n, body) for page in PAGES if page.name not in PYTHON_RUN_ELSEWHERE
                 for n, body in enumerate(_blocks(page.read_text(encoding="utf-8"), "python"))]


def test_the_python_blocks_are_found():
    assert any(page.name == "core.md" for page, _, _ in PYTHON_BLOCKS)


@pytest.mark.parametrize("page, n, body", PYTHON_BLOCKS,
                         ids=[f"{p.relative_to(DOCS)}[{n}]" for p, n, _ in PYTHON_BLOCKS])
def test_python_block_runs(page, n, body, tmp_path):
    done = subprocess.run([sys.executable, "-c", body], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          env={**__import__("os").environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, f"docs/{page.relative_to(DOCS)}, python block {n}:\n{done.stderr[-3000:]}"


def test_the_tutorial_runs_in_order(tmp_path):
    """Every command of docs/tutorial.md (the install line aside) and then its Python block, in
    one directory: the run, the sweep, the table (every job ok, the explicit job at 1.5× unstable)
    and the figure."""
    text = (DOCS / "tutorial.md").read_text(encoding="utf-8")
    env = {**__import__("os").environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}
    ran = []
    for block in _blocks(text, "bash"):
        for line in block.splitlines():
            words = shlex.split(line, comments=True)
            if not words or "pip" in line:
                continue
            if words[0] == "decrun":
                argv = [sys.executable, "-m", "decrun", *words[1:]]
            elif words[0] == "decrun-table":
                argv = [sys.executable, "-c", "import sys; from decrun.runner.command.table import table_main; "
                        "sys.exit(table_main(sys.argv[1:]))", *words[1:]]
            else:
                raise AssertionError(f"docs/tutorial.md: a command this test does not know: {line}")
            done = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
            assert done.returncode == 0, f"{line}\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
            ran.append((words[0], done.stdout))
    assert [w for w, _ in ran] == ["decrun", "decrun", "decrun-table"]
    table = ran[-1][1]
    rows = [r for r in table.splitlines() if re.match(r"\|\s*\d", r)]
    assert len(rows) == 4 and sum("false" in r for r in rows) == 1, table
    assert (tmp_path / "outputs" / "runs" / "first" / "smoothing.png").is_file()
    (body,) = _blocks(text, "python")
    done = subprocess.run([sys.executable, "-c", body], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "first_figure.png").stat().st_size > 10_000
    import matplotlib.image

    image = matplotlib.image.imread(tmp_path / "first_figure.png")[..., :3]
    ink = (image < 0.6).any(axis=2)  # text and lines on the white figure
    rows, cols = np.nonzero(ink)
    height, width = image.shape[:2]  # the x-label inside, not cut at the bottom (it was: ink in the last row)
    assert rows.max() < height - 2 and rows.min() > 1 and cols.min() > 1 and cols.max() < width - 2


def test_the_cluster_page_shows_the_shipped_launcher_config(site):
    """docs/cluster.md includes conf/hydra/launcher/slurm_example.yaml (pymdownx.snippets, the
    build fails on a missing file): the built page shows every line of the file."""
    raw = (DOCS / "cluster.md").read_text(encoding="utf-8")
    assert '```yaml\n--8<-- "conf/hydra/launcher/slurm_example.yaml"\n```' in raw
    text = _text(site / "cluster" / "index.html")
    lines = [line.strip() for line in (ROOT / "conf/hydra/launcher/slurm_example.yaml").read_text().splitlines()]
    missing = [line for line in lines if line and line not in text]
    assert not missing and "--8<--" not in text, missing


# ---------------------------------------------------------------- the inventory of fenced blocks


def fenced_blocks(text: str) -> list[tuple[int, str, str]]:
    """(line number, language, body) of every fenced block of a Markdown page, in order (a fence
    without a language gives ``""``; an indented fence closes at its own indentation)."""
    lines, found, i = text.splitlines(), [], 0
    while i < len(lines):
        opening = re.match(r"^(\s*)(`{3,})\s*([\w+-]*)", lines[i])
        if not opening:
            i += 1
            continue
        end = i + 1
        while end < len(lines) and not re.match(rf"^\s*{opening.group(2)}\s*$", lines[end]):
            end += 1
        found.append((i + 1, opening.group(3), "\n".join(lines[i + 1:end])))
        i = end + 1
    return found


def _module(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(ROOT / "tests"))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / "tests"))
    return module


#: blocks (page, the block's first line) and lines of bash blocks (page, the line) no test runs
#: as written, each with the reason; or run by a test the rules of :func:`runner_of` do not know
NOT_RUN = {
    # installs: a new venv and PyPI; .ci/run installs the same way (with the test extras) and runs the suite
    ("README.md", "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/decrun"):
        "not run: an install from PyPI into a new venv (network); .ci/run installs the same way",
    ("docs/index.md", "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/decrun"):
        "not run: an install from PyPI into a new venv (network); .ci/run installs the same way",
    ("docs/tutorial.md", "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/decrun"):
        "not run: an install from PyPI into a new venv (network); .ci/run installs the same way",
    ("README.md", 'python3 -m venv .venv && .venv/bin/pip install -e ".[test,slurm,ray,optuna]" && '
                  '.venv/bin/python -m pytest -n auto --maxprocesses=4'):
        "run by CI: .ci/run reads this line from README.md and runs it (the whole suite)",
    ("docs/viewer.md", 'pip install -e ".[view]"'):
        "not run: an install from PyPI (network); the viewer test needs the view extra installed",
    ("docs/viewer.md", "decrun-view outputs/runs/field --list"):
        "tests/runner/results/test_view.py (test_the_viewer_pages_commands_run_as_written)",
    ("docs/viewer.md", "decrun-view outputs/runs/field --field omega --screenshot field.png"):
        "tests/runner/results/test_view.py (test_the_viewer_pages_commands_run_as_written)",
    # benchmarks: minutes on a quiet machine; the pages state each number's command, commit and machine
    ("docs/performance.md", "python benchmarks/bench_operators.py --repeat 5   # 82k, 328k, 1.31M triangles"):
        "not run: a benchmark (minutes of a quiet machine); the page states its numbers' command, commit and machine",
    ("docs/performance.md",
     "python benchmarks/bench_small_run.py --repeat 9 --best cpu --reference /path/to/a/checkout/of/the/commit/before"):
        "not run: a benchmark (fresh processes of two checkouts, best of 5); the page states its numbers' commit and machine",
    ("docs/robustness.md", ".venv/bin/python benchmarks/mutation_check.py            # all (~20 min on 2 busy cores)"):
        "not run: ~20 min; tests/test_mutation_check.py checks every planted bug still matches the code",
    ("docs/robustness.md", '.venv/bin/python benchmarks/mutation_check.py -k flux    # those whose name contains "flux"'):
        "not run: minutes; tests/test_mutation_check.py checks every planted bug still matches the code",
    ("docs/tracking.md", "mlflow server --backend-store-uri sqlite:///mlflow.db --host 127.0.0.1 --port 5000"):
        "tests/runner/results/test_tracker_ui.py (starts this server and opens the UI)",
    ("docs/extending.md", 'PYTHONPATH=. decrun "hydra.searchpath=[file://$PWD/my_conf]" operator=uniform'):
        "tests/runner/config/test_extending.py (test_the_extending_pages_plugin_runs_as_written, by bash as written)",
    ("docs/cluster.md", "decrun -m hydra/launcher=slurm_example app.dt=0.001,0.002"):
        "not run: partition `compute` is an example cluster's; tests/runner/sweep/test_sweeps.py composes the "
        "launcher config (test_the_readme_slurm_launcher_config_composes), test_slurm.py runs submitit_slurm",
    # pages' configs
    ("docs/cluster.md", '--8<-- "conf/hydra/launcher/slurm_example.yaml"'):
        "the shipped file itself (test_the_cluster_page_shows_the_shipped_launcher_config)",
    ("docs/extending.md", "# my_conf/operator/uniform.yaml"):
        "tests/runner/config/test_extending.py (written from the page, then run)",
    ("docs/tracking.md", "# my_conf/tracker/wandb.yaml"):
        "not run: needs wandb and an account; test_extending.py runs a toy tracker of the same shape",
    # listings and outputs: nothing to run
    ("README.md", "decrun/runner/   the command line (Hydra), config schemas and plugin building, mesh sources and"):
        "a listing of the layers, not a command",
    ("docs/architecture.md", "decrun/runner/   the command line (Hydra), config schemas and plugin building, mesh "
                             "sources and"): "a listing of the layers, not a command",
    ("docs/architecture.md", "runner/api.py        decrun.run / decrun.sweep: the command's Hydra app run in your "
                             "process"): "a listing of modules, not a command",
    ("docs/running.md", "outputs/runs/<YYYY-mm-dd_HH-MM-SS>_<6 hex>/"): "a listing of a run directory",
    ("docs/tracking.md", "decrun: tracker=mlflow: 2 jobs under run 3f1c… (3 sent) in sqlite:////home/me/work/mlflow.db"):
        "an example output (its form: tests/runner/results/test_tracker.py)",
    ("docs/tracking.md", "decrun: warning: tracker=mlflow could not log to http://127.0.0.1:5000 (MlflowException: …); "
                         "the files in outputs/sweeps/… are complete; to log them: decrun-track outputs/sweeps/… "
                         "tracker=mlflow tracker.uri=http://127.0.0.1:5000"):
        "an example output (its form: tests/runner/results/test_tracker.py)",
    ("docs/running.md", "grep -h content_sha256 outputs/runs/A/metrics.json outputs/runs/B/metrics.json"):
        "test_the_running_pages_grep_compares_two_runs (below)",
    ("docs/apps/writing.md", "error: solver.method: must be one of auto | cg | minres | gmres | bicgstab, got 'lsqr' "
                             "(e.g. solver.method=auto)"): "an output (tests/runner/config/test_choices.py makes it)",
    ("docs/models.md", "expr   := number | name | call | expr OP expr | -expr | +expr | (expr)"):
        "the grammar of the model language, not a command",
    ("docs/models.md", "⟨K⁻¹ u, v⟩ − ⟨p, d v⟩ = −∫_∂Ω pb tr v          (u = −K ∇p, integrated by parts)"):
        "mathematics, not a command",
    ("docs/models.md", "[ ⋆_{n−1}    −K d_{n−1}ᵀ ⋆_n ] [u]   [ −K B pb ]"): "mathematics, not a command",
}


def _first_line(body: str) -> str:
    return next((line for line in body.splitlines() if line.strip()), "")


def runner_of(page: str, language: str, body: str, line: str | None, known: dict) -> str | None:
    """The test that runs ``line`` of a bash block (``line`` None: the whole block) of ``page``,
    found from what those tests read: None when no rule applies (then :data:`NOT_RUN` must)."""
    examples, models, elsewhere = known["examples"], known["models"], known["elsewhere"]
    if language == "bash" and line is not None:
        command = known["without_comment"](line)
        words = shlex.split(line, comments=True)
        if page == "docs/models.md":
            return "tests/test_model_docs.py" if shlex.join(words) in models else None
        if page in elsewhere and words and words[0].startswith("decrun"):
            return elsewhere[page]
        if page == "docs/cluster.md" and line in known["laptop_to_cluster"]:
            return "tests/runner/sweep/test_laptop_to_cluster.py"
        if command in known["syntax"]:
            return "shows syntax, not a command (SYNTAX of tests/runner/config/test_examples.py)"
        if command in examples and "hydra/launcher=slurm" not in command:  # that test skips a SLURM sweep
            return "tests/runner/config/test_examples.py"
        return None
    if language == "python":
        name = str(Path(page).relative_to("docs")) if page.startswith("docs/") else page
        if name in PYTHON_RUN_ELSEWHERE:
            return PYTHON_RUN_ELSEWHERE[name]
        return "tests/test_docs.py (test_python_block_runs)" if (page, body) in known["python"] else None
    if page == "docs/models.md" and (language, body) in known["model_blocks"]:
        return "tests/test_model_docs.py"
    return None


def _known() -> dict:
    examples = _module(ROOT / "tests" / "runner" / "config" / "test_examples.py", "decrun_docs_examples")
    models = _module(ROOT / "tests" / "test_model_docs.py", "decrun_docs_models")
    text = (DOCS / "models.md").read_text(encoding="utf-8")
    walked = {shlex.join(shlex.split(line, comments=True))
              for title in models.WHOLE_SECTIONS for language, body in models.blocks(models.section(text, title))
              if language == "bash" for line in body.splitlines() if shlex.split(line, comments=True)}
    model_blocks = {(language, body.rstrip("\n")) for title in models.WHOLE_SECTIONS
                    for language, body in models.blocks(models.section(text, title))}
    model_blocks |= {("yaml", body.rstrip("\n")) for body in models.excerpt_blocks(text)}
    model_blocks |= {("text", body.rstrip("\n")) for body in models.command_output_blocks(text)}
    cluster = (DOCS / "cluster.md").read_text(encoding="utf-8")
    laptop = re.search(r"<!-- laptop-to-cluster -->\n```bash\n(.*?)```", cluster, re.S).group(1)
    return {"examples": {c for _, c in examples.EXAMPLES}, "syntax": set(examples.SYNTAX),
            "without_comment": examples.without_comment,
            "models": walked | {c for c, _ in models.PAGE_COMMANDS},
            "model_blocks": model_blocks,
            "elsewhere": {page: test for page, test in examples.RUN_ELSEWHERE.items() if page != "docs/models.md"},
            "laptop_to_cluster": set(laptop.splitlines()),
            "python": {(f"docs/{p.relative_to(DOCS)}", body.rstrip("\n")) for p, _, body in PYTHON_BLOCKS}}


def inventory() -> list[tuple[str, int, str, str | None]]:
    """(page, line, what: a bash line or a block's first line, who runs it or why not) of every
    fenced block of README.md and the docs pages; who is None for one neither run nor listed."""
    known, rows = _known(), []
    for path in [ROOT / "README.md", *PAGES]:
        page = str(path.relative_to(ROOT))
        for number, language, body in fenced_blocks(path.read_text(encoding="utf-8")):
            if language == "bash":
                for offset, line in enumerate(body.splitlines(), start=1):
                    if not line.strip() or line.lstrip().startswith("#"):
                        continue
                    who = runner_of(page, language, body, line, known) or NOT_RUN.get((page, line))
                    rows.append((page, number + offset, line, who))
            else:
                first = _first_line(body)
                who = runner_of(page, language, body.rstrip("\n"), None, known) or NOT_RUN.get((page, first))
                rows.append((page, number, first, who))
    return rows


def test_every_fenced_block_is_run_or_listed():
    """Each fenced block of README.md and docs/ (each line of a bash block) is run by a test —
    found from what that test reads (test_examples' EXAMPLES, test_model_docs' commands and
    blocks, the Python blocks above, the laptop-to-cluster block) — or listed in NOT_RUN with its
    reason; no entry of NOT_RUN is left over from a block that changed."""
    rows = inventory()
    missing = [f"{page}:{line}: {what!r}" for page, line, what, who in rows if who is None]
    assert not missing, ("a block no test runs: make a test run it, or list it in NOT_RUN (tests/test_docs.py) "
                         "with the reason:\n" + "\n".join(missing))
    seen = {(page, what) for page, _, what, _ in rows}
    stale = [key for key in NOT_RUN if key not in seen]
    assert not stale, f"NOT_RUN lists blocks no page has (edited or removed): {stale}"
    assert len(rows) >= 60 and {page for page, *_ in rows} >= {"README.md", "docs/models.md", "docs/cluster.md"}


def test_the_running_pages_grep_compares_two_runs(tmp_path):
    """docs/running.md's ``grep`` line as written (by bash) on two runs of one config made as
    outputs/runs/A and B: two lines, the same content hash (a 64-hex sha256) in each."""
    (line,) = [line for block in _blocks((DOCS / "running.md").read_text(encoding="utf-8"), "bash")
               for line in block.splitlines() if line.startswith("grep ")]
    env = {**__import__("os").environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}
    for name in ("A", "B"):
        done = subprocess.run([sys.executable, "-m", "decrun", "mesh.subdiv=1", "app.steps=3", "figures=false",
                               f"hydra.run.dir=outputs/runs/{name}"], cwd=tmp_path, capture_output=True, text=True,
                              timeout=300, env=env)
        assert done.returncode == 0, done.stderr[-2000:]
    done = subprocess.run(["bash", "-c", line], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    hashes = [re.search(r'"content_sha256":\s*"([0-9a-f]{64})"', out) for out in done.stdout.splitlines()]
    assert len(hashes) == 2 and all(hashes) and hashes[0].group(1) == hashes[1].group(1), done.stdout
