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
  tests/test_model_docs.py).
"""

from __future__ import annotations

import html
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.rglob("*.md"))
#: python blocks another test runs: page → that test
PYTHON_RUN_ELSEWHERE = {"running.md": "tests/runner/test_api.py", "models.md": "tests/test_model_docs.py",
                        "tutorial.md": "test_the_tutorial_runs_in_order (below)"}
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
    assert "measurements.md" in text  # quiet-machine numbers only through the measurements page
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
                argv = [sys.executable, "-c", "import sys; from decrun.runner.cli import table_main; "
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
