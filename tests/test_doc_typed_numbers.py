"""No measured number is typed into README.md or any docs page: they come from docs/numbers.json.

A page shows a measured number as ``{{ numbers.<run>.<name> }}`` (scripts/doc_numbers.py makes it,
tests/test_numbers.py reruns it). This test reads README.md and every docs/**/*.md — a page
added later too; NOT_HERE names the pages another guard checks — and in each the prose (the
sections TIMING_SECTIONS names left out: benchmark timings that state their command, commit and
machine, each heading with why) — what is left
after code blocks, inline code, placeholders, images, link targets, HTML comments and references
(§5.2, eq. 5.9, Fig. 6.9, Figs. 7.15–7.17, ch. 5, Theorem 5) are taken out — and fails on every
number of two or more digits, with a decimal point or an exponent that no phrase of the page's
allow-list covers. Single digits are not checked (form degrees, "2×", "step 2": too many to list,
and a page's small counts are placeholders anyway); a measured one is still a placeholder.

The allow-list holds what is not measured: theory (2h̄²/π², l(l+1)), config values the page
documents (defaults, the mesh a table was made on, an experiment's parameters), thresholds and
constants of the code, years of citations — each phrase with why. A phrase that no longer
occurs on its page fails too, so the list cannot outlive the text it allows.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from page_prose import numbers_in, prose

ROOT = Path(__file__).resolve().parents[1]

#: pages not checked here, each with why; every other page — README.md and every docs/**/*.md,
#: one added later too — is checked
NOT_HERE: dict[str, str] = {
    "apps/fluid.md": "tests/test_fluid_page_numbers.py guards it (and the gallery's fluid sections)",
}


def _all_pages() -> list[str]:
    docs = sorted(path.relative_to(ROOT / "docs").as_posix() for path in (ROOT / "docs").rglob("*.md"))
    return ["README.md", *docs]


#: the pages checked: README.md (repository root) and docs/<page>
PAGES = [page for page in _all_pages() if page not in NOT_HERE]

#: page → headings whose sections (up to the next heading of the same or a higher level) are
#: benchmark timings: machine-dependent, so typed, each stating its command, commit and machine
_TIMED = "benchmark timings: the section states its command, commit and machine"
TIMING_SECTIONS: dict[str, dict[str, str]] = {
    "performance.md": {
        "Measured": _TIMED + " (the operators' table, the fluid channel's before/after)",
        "Not reached": "timing ratios of the operators' ### Measured table (command, commit, machine there)",
        "Sparse Cholesky (CHOLMOD)": _TIMED, "A small run": _TIMED,
    },
    "measurements.md": {heading: _TIMED + " (the page's header: every table says its command and commit)" for heading in (
        "The DEC core: operators", "Linear solvers", "Galerkin stars and the intrinsic Delaunay Laplacian",
        "Volumes", "The command line", "The iterative solver", "Sweeps", "Fluids", "Models")},
    "tracking.md": {"Cost": _TIMED},
    "README.md": {"Speed": _TIMED + " (the quiet-machine numbers the performance issue asks the README to state)"},
    "robustness.md": {"Mutation check": "counts of failing tests per planted bug from benchmarks/mutation_check.py "
                                        "(about 20 minutes of test runs): a record stating its command and commit (d71f3a2)"},
}


def path_of(page: str) -> Path:
    """The file of a page name: ``README.md`` at the repository root, the others under docs/."""
    return ROOT / page if page == "README.md" else ROOT / "docs" / page


def without_timing_sections(text: str, headings: dict[str, str]) -> str:
    """``text`` with the sections under ``headings`` blanked (same length, same lines); a heading
    that is not on the page is an error, so the list cannot outlive the page."""
    lines = text.splitlines(keepends=True)
    level_of = [len(m.group(1)) if (m := re.match(r"(#{1,6}) ", line)) else 0 for line in lines]
    in_fence, fenced = False, []
    for line in lines:
        if re.match(r"\s*(```|~~~)", line):
            in_fence = not in_fence
        fenced.append(in_fence)
    level_of = [0 if fenced[i] else level for i, level in enumerate(level_of)]
    for heading in headings:
        starts = [i for i, line in enumerate(lines) if level_of[i] and line.strip("# \n") == heading]
        if not starts:
            raise AssertionError(f"timing section {heading!r} is not a heading of the page")
        for start in starts:
            end = next((j for j in range(start + 1, len(lines)) if level_of[j] and level_of[j] <= level_of[start]),
                       len(lines))
            for j in range(start + 1, end):
                lines[j] = re.sub(r"[^\n]", " ", lines[j])
    return "".join(lines)


#: page → phrases whose numbers are not measurements (phrase: why)
ALLOWED: dict[str, dict[str, str]] = {
    "README.md": {"Python ≥ 3.10": "a requirement"},
    "cluster.md": {
        "60 minutes per job, at most 64 jobs at once": "the example launcher config's values",
        "(20 by default: the command ends within ~25 s)": "the config default `hydra.sweeper.connect_timeout` and "
                                                          "what it bounds",
    },
    "config.md": {
        "max(200, 10 √n) iterations": "the rule of the code", "1000× smaller drop tolerance": "a constant of the code",
        "(1e-14)": "the config default `solver.tol`", "to 1e-8 (": "the tolerance of the test named",
        "Eq. 5.9": "a reference", "to ≤ 1e-9 (": "the tolerance the tests hold the solvers to",
    },
    "robustness.md": {
        "(agreement 1e-13)": "the tolerance the dense cross-checks hold (tests/apps/test_hodge.py, test_parametrization.py)",
        "|x\\| > 1e150": "a bound of the code", "size range 1e-30 … 1e30": "bounds of the code",
        "down to 1e-300": "the range the fix handles", "diagonal 1.73e+100": "the example input's size",
        "a word over 160 characters (a 120 kB": "a bound of the code and the example input",
        "| 130 / 143 |": "exit codes (128 + SIGINT, 128 + SIGTERM)",
        "or 100k characters (": "the hostile input of tests/runner/test_hostile_models.py (a name of 100 000 characters)",
        "a chain of more than 300 definitions": "a bound of the code (decrun.apps.model.MAX_DEFINITION_CHAIN)",
    },
    "running.md": {
        "carry 24 random bits": "a constant of the code",
        "~10 ms per small result (the default run's 170 kB, on the loaded 2-core project\nmachine), 1.2 s for 138 MB":
            "timing (machine-dependent, not regenerated)",
        "0.25 s per 400 MB": "timing (machine-dependent, not regenerated)",
        "(10 000 by\ndefault": "the config default `hydra.sweeper.max_jobs`",
        "max_jobs=10000: this sweep has 100,000 jobs (app.dt: 100 values × mesh.noise: 1000 values)":
            "the refusal's message for the grid shown (101 − 1 and 1000 − 0 values)",
        "max_jobs=100000": "the override the message names",
        "4,210 of 10,000 jobs checked (42 %)": "an example of the progress line",
        "(4,210 of 10,000 jobs checked)": "an example of the message",
        "(60 by\ndefault)": "the config default `checkpoint.seconds`", "24 seeded TPE trials": "the sweeper's config",
        "(20 by default)": "the config default `hydra.sweeper.connect_timeout`",
        "deeper than 64 levels": "a bound of the code", "(10 000) jobs": "the config default `hydra.sweeper.max_jobs`",
    },
    "tracking.md": {"127.0.0.1:5000": "the MLflow UI's default address"},
    "measurements.md": {"Python 3.11": "the machine's Python"},
    "performance.md": {
        "(20·4^s triangles)": "the icosphere's face count (formula)",
        "(dt = 0.005)": "the channel's time step (config)", "(10 steps)": "the comparison's length",
        "at t = 0.6, dt = 0.0025": "Fig. 7.15's end time and time step (config)",
        "the 1e-6 those numbers": "the tolerance of the test named", "beyond 1e-12 relative": "the test's threshold",
        "dt = 0.02,": "the run's time step", "(dt = 0.001, 1/s;": "the drift's time step (parameter)",
        "at t = 0.6 (": "Fig. 7.15's end time", "dt = 0.0025, 0.005, 0.0075": "Fig. 7.15's time steps (config)",
        "pinned to 1e-6": "the tolerance of the test named",
        'mesh.target_faces=12000 "app.inflow=[10.0, 0.0]" app.initial=zero app.viscosity=0.02':
            "a command (an indented code block)",
    },
    "tutorial.md": {
        "Python ≥ 3.10": "a requirement",
        "icosphere with 162\nvertices": "the command's mesh (icosphere, mesh.subdiv=2: 10·4²+2 vertices)",
        "at 1.5 times": "the sweep's parameter (shown in its command)",
        "at 1.5 × the critical step": "the sweep's parameter",
    },
    "core.md": {
        "Meyer et al. 2003": "citation", "Sharp &\nCrane 2020": "citation",
        "to 1e-10 in the tests": "the tolerance of a test",
        "25×25 grid": "the experiment's mesh (config)", "50 jobs": "the sweep's size: 5 variants × 5 meshes × 2 apps",
        "| 15 ms |": "timing (machine-dependent; not regenerated)",
        "| 13 ms |": "timing (machine-dependent; not regenerated)",
        "| 38 ms |": "timing (machine-dependent; not regenerated)",
    },
    "volumes.md": {
        "(4e6) tetrahedra": "the config default `mesh.max_tets`", "about 1.8 × volume / max_volume": "TetGen's estimate",
    },
    "outputs-and-sweeps.md": {
        "rounded at 1e-9": "a constant of the code", "at least 0.9 edge lengths": "a constant of the code",
        "smaller than 10 pixels": "a constant of the code", "(10–150 s)": "timing (machine-dependent)",
        "at most 60 frames, 10 per second": "constants of the code",
        "on a 300-step run (1280 faces)": "timing: the run it was measured on (machine-dependent)",
        "1.25× the compute time instead of 3.9×": "timing (machine-dependent)",
    },
    "apps/smoothing.md": {
        "(0.75)": "the config default `app.dt_factor`", "differ > 20×": "a constant of the code",
        "normal noise 0.5, 10 steps": "the experiment's config", "% at 0.75×": "the config default",
        "(subdiv 3, 642 vertices, noise 0.3): 10 implicit steps": "the default config (10·4³+2 vertices)",
        "dt = 0.75 ×": "the config default",
    },
    "apps/parametrization.md": {
        "[0,1]²": "the target square", "Floater 2003": "citation", "(12 jobs)": "the sweep's size (3 borders × 4 weights)",
        "z = 0.15 sin(π(x+½))": "the test surface", "30 × 30 grid": "the test surface",
        "embeds with < 1°": "a bound the table above shows",
    },
    "apps/vector_field.md": {"at (0.3, 0.6)": "the experiment's source (config)", "λ = 0.2 / 1 / 5": "the sweep's values"},
    "apps/hodge.md": {"energy share ≤ 1e-16": "a threshold of the code"},
    "apps/spectrum.md": {
        "σ = −0.01/h̄²": "a constant of the code", "below 1e-8 (or 100 ×": "the convergence threshold of the code",
        "M-orthonormal to 1e-6": "a threshold of the code", "first 10 eigenvalues": "the table's definition",
        "unit icosphere 642 vertices": "the mesh (subdiv 3: 10·4³+2 vertices)",
        "24×24 grid": "the mesh (config)", "16×16, jittered": "the mesh (config)",
    },
    "apps/writing.md": {"longer than 60 lines": "a rule of the code base"},
    "models.md": {
        "densely, up to 400 unknowns": "a limit of the code (decrun.methods.model.stability)",
        "|e^{dt λ}|))^steps, exceeds 10": "the explicit check's rule (a constant of the code)",
        "passes (× 0.9, a whole": "the explicit check's margin (a constant of the code)",
        "(to 1e-9 of hi − lo)": "the bounds check's tolerance (a constant of the code)",
        "at dt = 1.25).": "the example's config value (Allen–Cahn under imex)",
        ": 0.9 ×": "the suggested step's rule for other apps (0.9 × their critical step, a constant of the code)",
        "is min(0.9 × the stability": "the suggested step's rule (a constant of the code)",
        "(l = 3: e^{−12k t})": "theory: l(l+1) = 12",
        "| 0.01, null |": "config defaults (`dt`, `t_end`)", "| 1e-6, 1e-9 |": "config defaults (`rtol`, `atol`)",
        "more than 4000 characters or 200 levels of nesting": "limits of the code",
        "2.785 for RK4": "a constant of the code (RK4's stability interval)",
        "at t = 0.1, l = 1/2/3": "the experiment's end time (config)", "at nx = 65 (square)": "the mesh (config)",
        "over 10 periods": "the benchmark's run length (config)",
        "Wardetzky 2013": "citation", "Pearson 1993's": "citation",
        "to 1e-12 over 100 steps": "the tolerance and length of a test",
        "spots at (0.035, 0.065), stripes at (0.04, 0.06), uniform at k = 0.075": "the models' constants (config)",
        "std of v > 0.02": "the metric's threshold (config)",
        "vs −0.1 (B = 1.8)": "theory: Re λ = (B − 1 − A²)/2 at the config's B", "vs 0.1 (B = 2.2)": "theory at the config's B",
        "the default run's 1000 steps": "the config's step count",
        "monotone at dt = 1e-3 … 1e-1 (tests)": "the steps the tests run",
        "at t = 0.1 to": "the times the count is taken at", "at t = 0.5 (the regions": "the experiment's end time (config)",
        "(CISM: 6.43 / 9.06 m RMS at 2 km)": "citation (CISM's published scores)",
        "potpourri3d's 1e-6·I shift": "a constant of potpourri3d",
        "crank_nicolson, dt = 1e-4, t = 0.1)": "the experiment's config",
        "| 17 |": "the grid (config: nx = ny)", "| 33 |": "the grid (config: nx = ny)", "| 65 |": "the grid (config: nx = ny)",
        "a 96-gon, min angle 25°": "the mesh (config)",
        "| 0.01 |": "the mesh's max_area (config)", "| 0.0025 |": "the mesh's max_area (config)",
        "| 0.000625 |": "the mesh's max_area (config)", "| 0.00015625 |": "the mesh's max_area (config)",
        "(symplectic, dt = 0.005, 10 periods)": "the benchmark's config",
        "dt = 1 a, 200 a; CISM: 6.43 / 9.06 m RMS at 2 km)": "the experiment's config; citation",
        "same 200 steps": "the experiment's step count (config)",
        "Lipscomb et al. 2019): Halfar's (1981)": "citations",
        "60000·√0.125 m and height 2000·√0.125 m, n = 3, A = 1e-16 Pa⁻³ a⁻¹, ρ = 910 kg m⁻³,\ng = 9.8101 m s⁻², on the 60 km × 100 km grid":
            "the benchmark's constants and domain (config)",
        "run\n0 → 200 years": "the benchmark's end time (config)",
        "(CISM:\n6.43 and 9.06 m at 2 km; Decapodes' documented explicit run: max error ≈ 89 m)": "citations (published scores)",
        "The same 200 steps": "the experiment's step count (config)",
        "(≤ 1e-14 below)": "a bound the table below shows",
        ": 9, 17, 33 vertices a side": "the meshes (config)", ": 3, 6, 12 Kuhn cells a side": "the meshes (config)",
        "over 100 steps on": "the length of a test",
        "(TRiSK, Ringler et al. 2010)": "citation", "on the Voronoi cells (Ringler et al. 2010)": "citation",
        "(Thuburn et al. 2009)": "citation", "(Williamson et al.\n1992)": "citation",
        "(Thuburn, Ringler, Skamarock & Klemp 2009; Ringler et al.\n2010)": "citations",
        "graticules every 30°": "a constant of the code (decrun.runner.plots.sphere.GRATICULE)",
        "(the grid's spacing, 0.5°)": "the default of the option `resolution` (decrun.runner.plots.sphere)",
        "at most 100\n  characters": "a bound of the code (decrun.apps.model.PLOT_NAME_MAX)",
        "by its first 40 characters": "a constant of the code (the refusal echoes the name's first 40 characters)",
        "to 1e-12 over 20 steps": "the tolerance and length of a test (tests/apps/test_shallow_water_model.py)",
        "radius a = 6.37122e6 m, subdiv 4) at dt = 1600 s for 5 days": "the mesh preset (icosphere_earth) and the "
                                                                         "model's config (conf/app/shallow_water.yaml)",
        "dt ≲ 2.8/(": "theory: RK4's imaginary stability interval 2√2 (decrun.methods.williamson.stable_time_step)",
        "is at most\n  300 long": "a bound of the code (decrun.apps.model.MAX_DEFINITION_CHAIN)",
        "Python's stack holds about 450 links,\n  so beyond 300 it says":
            "the bound of the code and its reason (the comment of decrun.apps.model.MAX_DEFINITION_CHAIN)",
        "at most 10 000 nodes in one file": "a bound of the code (decrun.runner.io.config_files.MAX_ALIASED_NODES)",
        "subdiv 5 for 15 days": "the experiment's config (conf/experiment/williamson_tc5.yaml)",
        "composite Simpson on 20001 latitudes": "a constant of the code (sphere_functions.LATITUDE_SAMPLES)",
        "reference of **day 15**": "the stored reference's day (benchmarks/data/shallow_water_reference.json)",
        "reference of **day 10** (the day GME publishes); day 14,": "the stored references' days (benchmarks/data)",
        "(TC5 day 15, TC6 day 10)": "the stored references' days (benchmarks/data)",
        "publishes l2(h) 1.37e-3 (TC5) and 9.01e-3 (TC6) at\nsubdiv 5 and 7.21e-4 and 2.89e-3 at subdiv 6":
            "citation (GME's published errors, /work/shared/SHALLOW_WATER.md)",
    },
    "gallery.md": {
        "(1280 triangles, none obtuse)": "the mesh (icosphere subdiv 3: 20·4³ faces)",
        "(~1400 faces)": "the config's target face count",
        "(inflow 10 units/s, ν = 0.02) on 1400 and 2800 target faces": "the experiment's config",
        "at t = 0.6 s": "the experiment's end time (config)", "at 2800 faces": "the config's target face count",
        "(vertex 2199)": "the config's source vertex",
        "(F, k) = (0.035, 0.065), stripes at (0.04, 0.06)": "the models' constants (config)",
        "exceeds 0.02": "the metric's threshold (config)", "(B = 2.5,": "the model's constant (config)",
        "(B = 1.5,": "the override shown", "after 200 years": "the experiment's end time (config)",
        "(RK4, dt = 1600 s)": "the model's config (conf/app/shallow_water.yaml `dt`)",
        "(contours every 2e-5 s⁻¹ from −1e-4 to 1e-4, 0°–90°N)": "the plot's config (scripts/sphere_maps.py: "
                                                                "interval, value_range, latitudes)",
    },
}

#: a number: digits with thousands groups ("19 901", "40,962"), decimals, an exponent, a k/M suffix
#: ("28k"); not a subscript or index (d0, ⋆1, Δ_2, x^2), a version or a path
NUMBER = re.compile(r"(?<![\w.⋆_^/\\-])\d+(?:[  ]\d{3})*(?:[.,]\d+)*(?:e[−+-]?\d+)?(?:[kM](?!\w))?(?!\w)")
REFERENCE = re.compile(r"(?:§|\beqs?\.|\bFigs?\.|\bch\.|\bTheorem|\bTable)\s*\d+(?:\.\d+)*"
                       r"(?:\s*(?:[–,/-]|and)\s*\d+(?:\.\d+)*)*")


def page_prose(text: str) -> str:
    """``text`` with what is not prose blanked out (same length, same lines): what
    tests/page_prose.py blanks (code, placeholders, images, link targets, HTML comments) and
    references."""
    return prose(text, REFERENCE)


def typed_numbers(text: str, allowed: dict[str, str]) -> list[str]:
    """The numbers of ``text``'s prose that no allowed phrase covers, each as ``line N: number
    in «context»``."""
    body = page_prose(text)
    covered = [range(m.start(), m.end()) for phrase in allowed
               for m in re.finditer(re.escape(_normal(phrase)), _normal(body))]
    found = []
    for line, match in numbers_in(body, NUMBER):
        if re.fullmatch(r"\d", match.group(0)):
            continue
        if any(match.start() in span and match.end() - 1 in span for span in covered):
            continue
        context = " ".join(body[max(0, match.start() - 40):match.end() + 20].split())
        found.append(f"line {line}: {match.group(0)} in «{context}»")
    return found


def _normal(text: str) -> str:
    """Whitespace runs as single characters of the same count (so a phrase may break lines)."""
    return re.sub(r"\s", " ", text)


def page_text(page: str) -> str:
    """The page's markdown with its timing sections blanked."""
    return without_timing_sections(path_of(page).read_text(encoding="utf-8"), TIMING_SECTIONS.get(page, {}))


@pytest.mark.parametrize("page", PAGES)
def test_no_measured_number_is_typed_into_the_page(page):
    found = typed_numbers(page_text(page), ALLOWED.get(page, {}))
    assert not found, (f"{path_of(page).relative_to(ROOT)}: numbers typed by hand — make each a placeholder "
                       "{{ numbers.<run>.<name> }} (scripts/doc_numbers.py: a Run or a Source), or, if it is "
                       "theory or a config value, add its phrase to ALLOWED in tests/test_doc_typed_numbers.py:\n  "
                       + "\n  ".join(found))


@pytest.mark.parametrize("page", sorted(ALLOWED))
def test_every_allowed_phrase_is_on_its_page(page):
    body = _normal(page_prose(page_text(page)))
    stale = [phrase for phrase in ALLOWED[page] if _normal(phrase) not in body]
    assert page in PAGES and not stale, f"{page}: allowed phrases no longer on the page: {stale}"


def test_every_page_is_checked_here_or_says_where():
    """A page is checked unless NOT_HERE names it with the guard that checks it; the names of
    NOT_HERE and TIMING_SECTIONS are pages that exist."""
    pages = _all_pages()
    assert "README.md" in PAGES and "index.md" in PAGES and len(PAGES) + len(NOT_HERE) == len(pages)
    assert set(NOT_HERE) <= set(pages) and set(TIMING_SECTIONS) <= set(PAGES)


def test_a_timing_section_is_left_out_and_only_it():
    text = "# T\nmeasured 0.123\n## Cost\nfast: 12.5 ms\n### sub\n13 ms\n## Next\n0.456 again\n"
    assert [f.split(": ")[1].split(" ")[0] for f in typed_numbers(without_timing_sections(text, {"Cost": "x"}), {})] \
        == ["0.123", "0.456"]
    with pytest.raises(AssertionError, match="not a heading"):
        without_timing_sections(text, {"Costs": "x"})


def test_a_typed_measurement_is_found_and_a_placeholder_is_not():
    """The issue's examples: Fig. 6.9's 0.258 typed into the vector-field table, the 9722 of an
    enstrophy and Fig. 5.5's "20°" — each found, with a mesh size written "82k" or "12059-face";
    the same cells as placeholders, references, subscripts and code are not; an allowed phrase
    (one that breaks a line too) covers its numbers."""
    page = (ROOT / "docs" / "apps" / "vector_field.md").read_text(encoding="utf-8")
    allowed = ALLOWED["apps/vector_field.md"]
    assert typed_numbers(page, allowed) == []
    typed = page.replace("{{ numbers.fig6_9_none_nostroke.flux }}", "0.258", 1)
    assert [f.split(" in ")[0].split(": ")[1] for f in typed_numbers(typed, allowed)] == ["0.258"]
    text = ("The enstrophy ends at 9722 (Fig. 7.17, eq. 7.14, §6.4.4); the angle is 20° "
            "(`app.dt=0.0075`, {{ numbers.x.y }}) on the 82k-vertex scan,\na 12059-face channel, "
            "Δ2 of the 1-forms.\n```bash\ndecrun app.viscosity=0.08\n```\n")
    assert [f.split(" in ")[0].split(": ")[1] for f in typed_numbers(text, {})] == ["9722", "20", "82k", "12059"]
    assert [f.split(":")[0] for f in typed_numbers(text, {})] == ["line 1"] * 3 + ["line 2"]
    assert typed_numbers(text, {"ends at 9722": "x", "is 20°": "y", "the 82k-vertex scan, a 12059-face": "z"}) == []
