"""No measured number is typed into the fluid pages: each comes from ``docs/numbers.json``.

The prose of ``docs/apps/fluid.md`` and of the gallery's fluid sections (``## fig7_…``) is
scanned for numbers that look measured — a decimal (``0.147``, ``1.8e3``), an integer of three or
more digits (``1455``, ``12,059``), a percentage (``8 %``) or a factor (``×0.77``, ``0.95×``) —
outside ``{{ numbers.… }}`` placeholders, code blocks, inline code (commands, config keys) and
link targets (:data:`NOT_PROSE`, blanked by tests/page_prose.py as for the site-wide guard).
Small integers (a step count of two digits, "8, 16, 32 cells") are not flagged: too many are
parameters; the page makes its measured ones placeholders all the same.
What remains must be in ``ALLOWED``: a constant the page documents (a config default, a
parameter of a test or a benchmark, a tolerance a test states, a mesh size the thesis names) or
the thesis' own words, each with its reason. A measured number belongs in
``scripts/doc_numbers.py`` (a run or a source) and on the page as a placeholder.
"""

from __future__ import annotations

import re
from pathlib import Path

from page_prose import LINK_TARGET, numbers_in, prose

ROOT = Path(__file__).resolve().parents[1]

#: token → why it may be typed (not a measurement)
ALLOWED: dict[str, str] = {
    # config values of the experiments and the app (conf/experiment/fig7_*.yaml, conf/app/fluid.yaml)
    "0.0025": "Fig. 7.15's time steps (config)", "0.005": "time step / viscosity (config)",
    "0.0075": "Fig. 7.15's largest time step (config; the thesis' 'dt = 0.0075 starts to be unstable')",
    "0.02": "viscosity / time step (config)", "0.08": "viscosity (config)", "0.0": "viscosity (config)",
    "0.03": "Fig. 7.1's viscosity (config)", "0.6": "Fig. 7.15's t_end (config)",
    "0.4": "Fig. 7.17's t_end (config)", "0.01": "viscosity / time step of a test (parameter)",
    "0.001": "the drift's time step (parameter)", "1e-3": "the drift's time step (parameter)",
    "0.1": "the shadow's default threshold per step / obstacle radius (config)",
    "1e-10": "the shadow's perturbation (config)", "0.12": "the vortex pair's blob radius (test parameter)",
    "1400": "a target face count (config, the thesis' mesh)", "2800": "a target face count (config)",
    "5300": "a target face count (config)", "12000": "a target face count (config, the thesis' mesh)",
    "1280": "the icosphere of subdivision 3 (a test's and Fig. 7.1's mesh)",
    "100": "steps of a test / the shadow's window (parameter)", "1000": "steps of the unforced runs (parameter)",
    "1e-12": "the divergence bound and rise threshold tests hold (tolerance)",
    "1e-9": "a tolerance", "200": "steps of the inviscid channel runs (parameter)",
    "0.5": "the numbers test's tolerance of a growth rate (/s)", "2007": "the year of Elcott et al.",
    # regions and parameters the numbers are measured over (fixed by the measurement, not results)
    "0.2": "the inner square (0.2, 0.8)² of the cellular drift", "0.8": "the inner square (0.2, 0.8)²",
    "0.3": "the inflow strip x < 0.3", "0.05": "the wall band y < 0.05", "0.95": "the wall band y > 0.95",
    "1.9": "the outflow strip x > 1.9", "0.65": "the wake x ∈ (0.65, 1.5)", "1.5": "the wake x ∈ (0.65, 1.5)",
    "0.15": "the lattice jitter ≤ 0.15 h (parameter)", "2.5e-4": "the floor's time step (parameter)",
    # tolerances the tests state
    "0.2 %": "the viscous decay test's tolerance", "10 %": "the vortex pair test's tolerance",
    "3 %": "the wake test's tolerance", "0.1 %": "the numbers test's tolerance of enstrophy and energy",
    "25 %": "the numbers test's tolerance of a chaotic run", "30 %": "the numbers test's tolerance of a growth",
    # library constants
    "300,000": "GNU OpenMP's default spin count", "10000": "decrun's GOMP_SPINCOUNT",
    # the thesis
    "7.1": "Fig. 7.1", "7.4": "Fig. 7.4", "7.6": "Fig. 7.6", "7.9": "Fig. 7.9", "7.11": "eq. 7.11",
    "7.13": "eq. 7.13", "7.14": "Fig./eq. 7.14", "7.15": "Fig./eq. 7.15", "7.16": "Fig. 7.16",
    "7.17": "Fig. 7.17", "7.18": "Fig. 7.18", "7.2.1": "§7.2.1", "7.3": "§7.3", "6.4.2": "§6.4.2",
    "7.2.5": "§7.2.5", "6.4.4": "§6.4.4", "90.0": "a right angle (the bound the smoothing aims at)",
}

#: what is not prose here: code blocks, one-line inline code, link targets and number placeholders
NOT_PROSE = (re.compile(r"^```.*?^```", flags=re.M | re.S), re.compile(r"`[^`\n]*`"), LINK_TARGET,
             re.compile(r"\{\{\s*numbers\.[\w.]+\s*\}\}"))
#: a number that looks measured: a decimal or scientific number, an integer of 3+ digits (with
#: or without thousands separators), and any number with % after it or × before/after it
NUMBER = re.compile(r"(?<![\w.§])(\d+(?:,\d{3})+|\d+(?:\.\d+)+(?:e[+-]?\d+)?|\d+e[+-]?\d+|\d{3,})(?![\w])")
MARKED = re.compile(r"×\s?(\d+(?:\.\d+)?)|(?<![\w.])(\d+(?:\.\d+)?)\s?[%×]")


def typed_numbers(markdown: str) -> list[tuple[int, str]]:
    """(line, token) of every number in the prose that looks measured and is not allowed."""
    body = prose(markdown, not_prose=NOT_PROSE)
    lines = body.splitlines()
    numbers: dict[int, list[str]] = {}
    for n, m in numbers_in(body, NUMBER):
        numbers.setdefault(n, []).append(m.group(1))
    marked: dict[int, list[re.Match]] = {}
    for n, m in numbers_in(body, MARKED):
        marked.setdefault(n, []).append(m)
    found = []
    for n in sorted(numbers.keys() | marked.keys()):
        tokens, line = numbers.get(n, []), lines[n - 1]
        for m in marked.get(n, []):
            number = m.group(1) or m.group(2)
            if re.search(re.escape(number) + r"\s?%", line):  # a percentage: judged as one
                tokens = [t for t in tokens if t != number] + [f"{number} %"]
            elif number not in tokens:
                tokens.append(number)
        for token in dict.fromkeys(tokens):
            if token not in ALLOWED and token.replace(",", "") not in ALLOWED:
                found.append((n, token))
    return found


def fluid_sections(gallery: str) -> str:
    """The gallery's fluid sections (``## fig7_…`` up to the next ``## ``)."""
    parts = re.split(r"^(?=## )", gallery, flags=re.M)
    return "\n".join(part for part in parts if part.startswith("## fig7_"))


def test_the_fluid_page_types_no_measured_number():
    found = typed_numbers((ROOT / "docs" / "apps" / "fluid.md").read_text(encoding="utf-8"))
    assert not found, ("docs/apps/fluid.md types numbers that look measured (line, number) — make each a "
                       f"{{{{ numbers.… }}}} placeholder (scripts/doc_numbers.py) or allow it here with a reason: {found}")


def test_the_gallery_fluid_sections_type_no_measured_number():
    sections = fluid_sections((ROOT / "docs" / "gallery.md").read_text(encoding="utf-8"))
    assert "## fig7_15" in sections
    found = typed_numbers(sections)
    assert not found, f"docs/gallery.md's fluid sections type numbers that look measured: {found}"


def test_the_guard_finds_a_typed_measurement():
    page = "The drift is {{ numbers.fluid_drift.rigid_rotation_3_default }} /s at 1280 faces."
    assert typed_numbers(page) == []
    for typed, token in (("0.00271 /s", "0.00271"), ("1455 faces", "1455"), ("12,059 faces", "12,059"),
                         ("8 % of it", "8 %"), ("energy ×0.995", "0.995"), ("2.5× more", "2.5"),
                         ("4.2e3 /s", "4.2e3")):
        found = typed_numbers(f"It measured {typed}.\n")
        assert found == [(1, token)], (typed, found)
    # code and commands are not prose; a number after a code block is reported on its page line
    assert typed_numbers("run `decrun mesh.target_faces=5399`\n```bash\ndecrun app.dt=0.1234\n```\n") == []
    assert typed_numbers("```bash\ndecrun app.dt=0.1234\n```\nIt measured 0.00271 /s.\n") == [(4, "0.00271")]
