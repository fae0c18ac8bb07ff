"""``decrun-view``: every field of a run placed as its polyscope quantity, and headless screenshots
that show what the field is (decrun/runner/view.py).

The placement tests need no polyscope. The screenshot tests render through polyscope's EGL
backend in a child process; they skip with the reason where polyscope or EGL is missing, and
fail instead under CI=true (``.ci/run`` installs both)."""

from __future__ import annotations

import colorsys
import functools
import os
import subprocess
import sys

import numpy as np
import pytest

from decrun.runner.view import ViewError, edge_order, left_out_line, plan_view

from cli_processes import decrun, env


def _view(*args: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "decrun.runner.view", *args], cwd=cwd, env=env(),
                          capture_output=True, text=True, timeout=300)


@functools.lru_cache(maxsize=1)
def _headless_reason() -> str:
    """Why polyscope cannot render headless here ('' when it can)."""
    probe = ("import polyscope as ps; ps.set_allow_headless_backends(True); ps.init('openGL3_egl')")
    try:
        import polyscope  # noqa: F401
    except ImportError:
        return "polyscope is not installed (pip install 'decrun[view]')"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    if done.returncode:
        return "polyscope cannot start EGL here (Debian: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri): " \
               + (done.stderr.strip().splitlines() or ["?"])[-1]
    return ""


@pytest.fixture
def headless():
    reason = _headless_reason()
    if reason:
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI installs polyscope and EGL (.ci/run): {reason}")
        pytest.skip(reason)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Small runs of three apps: a vector field (1-form, sets, points), heat with u = ±z (a
    known height function) and a Hodge decomposition on tetrahedra."""
    root = tmp_path_factory.mktemp("view")
    made = {}
    for name, args in {
        "vector_field": ["app=vector_field", "mesh.subdiv=2"],
        "height": ["app=heat", "app.fields.u.initial=z", "app.t_end=0.002", "app.record_every=1"],
        "depth": ["app=heat", "app.fields.u.initial=-z", "app.t_end=0.002", "app.record_every=1"],
        "tets": ["app=hodge", "mesh=box", "mesh.cells=3"],
    }.items():
        done = decrun(*args, f"hydra.run.dir={root / name}", "progress=false", cwd=root)
        assert done.returncode == 0, done.stderr[-2000:]
        made[name] = root / name
    return made


def test_edge_order_is_polyscopes_walk():
    """polyscope numbers edges as first met walking the triangles' sides (v0v1, v1v2, v2v0):
    the permutation sends each of those to the run's edge with the same two vertices."""
    rng = np.random.default_rng(3)
    triangles = np.array([[0, 1, 2], [2, 1, 3], [3, 4, 2], [4, 0, 2]])
    edges = np.unique(np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]),
                              axis=1), axis=0)
    edges = edges[rng.permutation(len(edges))]
    flip = rng.random(len(edges)) < 0.5
    edges[flip] = edges[flip][:, ::-1]
    walked = []  # the walk written out, as polyscope's source does it
    for triangle in triangles.tolist():
        for j in range(3):
            key = tuple(sorted((triangle[j], triangle[(j + 1) % 3])))
            if key not in walked:
                walked.append(key)
    permutation, orientation = edge_order(triangles, edges)
    assert [tuple(sorted(edges[i])) for i in permutation] == walked
    assert np.array_equal(orientation, edges[:, 0] < edges[:, 1])


def test_edge_order_refuses_edges_that_are_not_the_sides():
    with pytest.raises(ViewError, match="not the sides"):
        edge_order(np.array([[0, 1, 2]]), np.array([[0, 1], [1, 2], [0, 3]]))


def test_every_field_has_its_quantity_or_a_reason(runs):
    """The app's declared outputs decide the kinds; nothing is silently dropped."""
    view = plan_view(runs["vector_field"])
    kinds = {q.name: q.kind for q in view.quantities}
    assert kinds["omega"] == "one_form" and kinds["face_vectors"] == "cell_vector"
    assert kinds["vertex_index"] == "vertex_scalar" and kinds["face_index"] == "cell_scalar"
    assert kinds["source_vertices"] == "vertex_set" and kinds["singular_faces"] == "cell_set"
    assert kinds["cluster_positions"] == "points"
    import h5py

    with h5py.File(runs["vector_field"] / "result.h5") as f:
        stored = set(f["fields"])
    assert stored == set(kinds) | set(view.left_out)

    heat = plan_view(runs["height"] / "result.h5")
    assert {q.name: (q.kind, q.series) for q in heat.quantities} == {"u": ("vertex_scalar", False),
                                                                    "u (series)": ("vertex_scalar", True)}
    assert set(heat.scalars) == {"mass", "dirichlet_energy"} and len(heat.steps) == 3

    tets = plan_view(runs["tets"])
    assert tets.dimension == 3
    assert {"exact", "coexact", "harmonic", "omega", "beta"} <= set(tets.left_out)
    assert "a 1-form on the edges of a volume" in left_out_line(tets.left_out)
    assert {q.kind for q in tets.quantities} == {"vertex_scalar", "cell_vector"}


def test_list_and_refusals_are_one_line(runs, tmp_path):
    done = _view(str(runs["vector_field"]), "--list", cwd=tmp_path)
    assert done.returncode == 0 and "omega\tone_form" in done.stdout
    done = _view(str(runs["vector_field"]), "--field", "omgea", "--screenshot", "x.png", cwd=tmp_path)
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "did you mean --field 'omega'?" in done.stderr
    done = _view(str(runs["height"]), "--step", "7", "--screenshot", "x.png", cwd=tmp_path)
    assert done.returncode == 2 and "recorded 3 steps" in done.stderr
    done = _view(str(tmp_path / "nothing"), cwd=tmp_path)
    assert done.returncode == 2 and "no result" in done.stderr and done.stderr.count("\n") == 1
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("name", ["result.h5", "result.h5.partial"])
def test_a_fifo_in_place_of_the_result_is_one_line_never_a_hang(tmp_path, name):
    """Issue 50, item 7: a FIFO where the result (or its journal) should be is refused before it
    is opened — opening it would wait for a writer forever."""
    run = tmp_path / "run"
    run.mkdir()
    os.mkfifo(run / name)
    # a child blocked on the FIFO (the failure this test catches) is killed at the timeout
    done = subprocess.run([sys.executable, "-m", "decrun.runner.view", str(run), "--list"], cwd=tmp_path,
                          env=env(), capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr[-2000:]
    assert f"{run / name}: not a regular file (a FIFO)" in done.stderr


def test_without_polyscope_one_line_install_hint(runs, tmp_path):
    code = ("import sys; sys.modules['polyscope'] = None; from decrun.runner.view import main; "
            f"sys.exit(main([{str(runs['height'])!r}, '--screenshot', 'x.png']))")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env(), capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.strip() == "error: decrun-view needs polyscope: pip install 'decrun[view]' " \
                                  "(or pip install polyscope)"


def _image(path) -> np.ndarray:
    import matplotlib.image

    return (matplotlib.image.imread(path)[..., :3] * 255).astype(np.int64)


def _extremes(image: np.ndarray) -> tuple[float, float, float, float]:
    """Mean rows of the most yellow and the most purple mesh pixels (viridis' two ends, told apart
    by hue, which shading does not change), and the mesh's top and bottom rows."""
    mesh = image.sum(axis=2) < 3 * 245  # not the white background
    rows, cols = np.nonzero(mesh)
    hue = np.array([colorsys.rgb_to_hsv(*(image[r, c] / 255))[0] for r, c in zip(rows, cols, strict=True)])
    hue = np.where(hue < 0.1, hue + 1, hue)  # viridis: yellow ~0.15 … purple ~0.8 (wrap the reds)
    yellow = rows[hue <= np.quantile(hue, 0.02)].mean()
    purple = rows[hue >= np.quantile(hue, 0.98)].mean()
    return yellow, purple, rows.min(), rows.max()


def test_screenshot_puts_the_extreme_colours_at_the_extreme_vertices(runs, tmp_path, headless):
    """u = z seen from the side with z up: viridis' top colour at the top of the sphere, its
    bottom colour at the bottom; u = −z the other way round."""
    for name, top_is_yellow in (("height", True), ("depth", False)):
        shot = tmp_path / f"{name}.png"
        done = _view(str(runs[name]), "--field", "u", "--screenshot", shot.name, "--size", "400x400", cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        yellow, purple, top, bottom = _extremes(_image(shot)[:, :400])  # the picture, not its colour bar
        span = bottom - top
        high, low = (yellow, purple) if top_is_yellow else (purple, yellow)
        assert high - top < 0.2 * span and bottom - low < 0.2 * span, (name, yellow, purple, top, bottom)


def test_a_scalar_screenshot_has_its_colour_bar_beside_the_picture(runs, tmp_path, headless):
    """u = z on the unit sphere: the picture keeps its size, a strip on its right holds a vertical
    viridis bar (yellow at the top, purple at the bottom, the colours of the picture's extremes) and
    nothing of the picture; a 1-form's screenshot (arrows, no colour scale) has no strip."""
    shot = tmp_path / "u.png"
    done = _view(str(runs["height"]), "--field", "u", "--screenshot", shot.name, "--size", "400x400", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    image = _image(shot)
    from decrun.runner.view import COLOUR_BAR_STRIP

    assert image.shape[:2] == (400, 400 + COLOUR_BAR_STRIP)
    strip = image[:, 400:]
    coloured = (np.ptp(strip, axis=2) > 60)  # saturated pixels: the bar (ticks and labels are grey)
    rows, cols = np.nonzero(coloured)
    assert rows.max() - rows.min() > 0.6 * 400 and cols.max() - cols.min() < 40  # one tall, thin bar
    column = strip[:, int(np.median(cols))]
    top, bottom = column[rows.min() + 2], column[rows.max() - 2]
    from matplotlib import colormaps

    viridis = (np.array(colormaps["viridis"]([1.0, 0.0]))[:, :3] * 255).astype(np.int64)
    assert np.abs(top - viridis[0]).max() < 12 and np.abs(bottom - viridis[1]).max() < 12, (top, bottom)
    one_form = tmp_path / "omega.png"
    done = _view(str(runs["vector_field"]), "--field", "omega", "--screenshot", one_form.name, "--size", "400x300",
                 cwd=tmp_path)
    assert done.returncode == 0 and _image(one_form).shape[:2] == (300, 400), done.stderr


def test_screenshots_of_two_fields_differ(runs, tmp_path, headless):
    shots = []
    for field in ("omega", "vertex_index"):
        shot = tmp_path / f"{field}.png"
        done = _view(str(runs["vector_field"]), "--field", field, "--screenshot", str(shot), "--size", "400x300",
                     cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        shots.append(_image(shot)[:, :400])  # the pictures (a scalar's has its colour bar beside it)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["omega.png", "vertex_index.png"]  # no imgui.ini here
    differ = np.abs(shots[0] - shots[1]).sum(axis=2) > 30
    assert differ.mean() > 0.05


def test_the_viewer_pages_commands_run_as_written(tmp_path, headless):
    """docs/viewer.md's commands in order in one directory (the install line aside: the view
    extra is what ``headless`` needs): the run, the field list naming ``omega``, and the
    screenshot, a picture of the mesh (not an empty frame)."""
    import re
    import shlex
    from pathlib import Path

    text = (Path(__file__).resolve().parents[3] / "docs" / "viewer.md").read_text(encoding="utf-8")
    (block,) = re.findall(r"^```bash\n(.*?)^```", text, flags=re.S | re.M)
    lines = [line for line in block.splitlines() if line.strip()]
    assert lines[0] == 'pip install -e ".[view]"' and len(lines) == 4, lines
    outputs = []
    for line in lines[1:]:
        words = shlex.split(line, comments=True)
        if words[0] == "decrun":
            done = decrun(*words[1:], cwd=tmp_path)
        else:
            assert words[0] == "decrun-view", line
            done = _view(*words[1:], cwd=tmp_path)
        assert done.returncode == 0, (line, done.stderr[-2000:])
        outputs.append(done.stdout)
    assert "omega\tone_form" in outputs[1]
    shot = _image(tmp_path / "field.png")
    mesh = shot.sum(axis=2) < 3 * 245
    assert 0.05 < mesh.mean() < 0.95 and np.ptp(shot[mesh], axis=0).max() > 50  # a coloured surface
