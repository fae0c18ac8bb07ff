"""The type checker finds nothing new: ``mypy decrun`` (the settings of ``[tool.mypy]`` in
pyproject.toml) reports no error that ``tests/mypy_baseline.txt`` does not list, and no
more errors than it lists. The baseline only shrinks: ``python tests/test_types.py
--update`` rewrites it with the errors that are left, and refuses to add one.

An error is known by its file, its code and its message — not its line, so an edit above
it does not make it new (a message's ``line N`` is written ``line N`` too). The check also
catches a planted error, and the update refuses a baseline that would grow."""

from __future__ import annotations

import collections
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BASELINE = Path(__file__).with_name("mypy_baseline.txt")
#: ``decrun/x.py:12: error: Message  [code]`` (mypy's default output)
ERROR = re.compile(r"^(?P<path>[^:\n]+\.pyi?):\d+(?::\d+)?: error: (?P<message>.*?)\s+\[(?P<code>[a-z-]+)\]$")

pytest.importorskip("mypy")


def mypy(cwd: Path, *paths: str) -> subprocess.CompletedProcess:
    """``mypy paths`` in ``cwd`` with the settings of the pyproject.toml found there."""
    return subprocess.run([sys.executable, "-m", "mypy", "--no-pretty", "--no-error-summary", *paths], cwd=cwd,
                          capture_output=True, text=True, timeout=900)


def errors(output: str) -> collections.Counter:
    """``"path: [code] message"`` → how often mypy reports it."""
    found: collections.Counter = collections.Counter()
    for line in output.splitlines():
        match = ERROR.match(line)
        if match:
            message = re.sub(r"\bline \d+", "line N", match["message"])
            found[f"{match['path']}: [{match['code']}] {message}"] += 1
    return found


def read_baseline() -> collections.Counter:
    lines = [line for line in BASELINE.read_text().splitlines() if line and not line.startswith("#")]
    return collections.Counter(lines)


def compare(found: collections.Counter, baseline: collections.Counter) -> list[str]:
    """What is wrong with ``found`` against ``baseline``: errors it does not list (or lists
    fewer times), and a total above its total."""
    problems = [f"new: {line}" + (f" (x{n - baseline[line]})" if n - baseline[line] > 1 else "")
                for line, n in sorted(found.items()) if n > baseline[line]]
    if sum(found.values()) > sum(baseline.values()):
        problems.append(f"{sum(found.values())} errors, the baseline has {sum(baseline.values())}")
    return problems


def test_mypy_reports_no_error_the_baseline_does_not_list():
    proc = mypy(REPO, "decrun")
    assert proc.returncode in (0, 1) and not proc.stderr.strip(), proc.stdout[-3000:] + proc.stderr[-3000:]
    found = errors(proc.stdout)
    problems = compare(found, read_baseline())
    assert not problems, ("mypy found errors the baseline tests/mypy_baseline.txt does not allow (fix them; the "
                          "baseline only shrinks):\n" + "\n".join(problems[:50]))
    fixed = sum(read_baseline().values()) - sum(found.values())
    if fixed:
        print(f"{fixed} baseline errors are fixed: shrink it with python tests/test_types.py --update")


def test_a_planted_error_is_found_and_is_not_in_the_baseline(tmp_path):
    (tmp_path / "pyproject.toml").write_text((REPO / "pyproject.toml").read_text())
    package = tmp_path / "decrun"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "planted.py").write_text('def area(n: int) -> int:\n    return n\n\n\narea("3")\n'
                                        "total: int = 'x'  # defined on line 2\n")
    found = errors(mypy(tmp_path, "decrun").stdout)
    assert found == {'decrun/planted.py: [arg-type] Argument 1 to "area" has incompatible type "str"; '
                     'expected "int"': 1,
                     'decrun/planted.py: [assignment] Incompatible types in assignment (expression has type "str", '
                     'variable has type "int")': 1}, found
    assert compare(found, collections.Counter()) == [*(f"new: {line}" for line in sorted(found)),
                                                     "2 errors, the baseline has 0"]
    assert compare(found, found + found) == []  # fewer than the baseline: fine (the baseline shrinks later)


def test_the_update_only_drops_lines():
    baseline = collections.Counter({"a.py: [x] one": 2, "b.py: [y] two": 1})
    assert updated(baseline, collections.Counter({"a.py: [x] one": 1})) == ["a.py: [x] one"]
    with pytest.raises(SystemExit, match="new errors"):
        updated(baseline, collections.Counter({"c.py: [z] three": 1}))


def updated(baseline: collections.Counter, found: collections.Counter) -> list[str]:
    """The baseline's lines that ``found`` still has (as often as both have them), sorted;
    SystemExit when ``found`` has errors the baseline does not allow."""
    problems = compare(found, baseline)
    if problems:
        raise SystemExit("new errors; the baseline does not grow:\n" + "\n".join(problems))
    return sorted((found & baseline).elements())


if __name__ == "__main__":
    if sys.argv[1:] != ["--update"]:
        raise SystemExit("usage: python tests/test_types.py --update  (shrinks tests/mypy_baseline.txt)")
    proc = mypy(REPO, "decrun")
    header = [line for line in BASELINE.read_text().splitlines() if line.startswith("#")]
    lines = updated(read_baseline(), errors(proc.stdout))
    BASELINE.write_text("\n".join([*header, *lines]) + "\n")
    print(f"tests/mypy_baseline.txt: {len(lines)} errors")
