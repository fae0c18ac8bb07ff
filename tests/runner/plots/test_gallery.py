"""The gallery (scripts/gallery.py → docs/gallery.md) shows every thesis-figure experiment
(conf/experiment/fig*.yaml; the others — operator_variants, dt_crit_search — are tables), the
model experiments that have a picture (darcy_convergence) and every shipped declarative model
(conf/app/<model>.yaml), each with the numbers of its run (placeholders of docs/numbers.json: tests/test_numbers.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


def gallery_module():
    spec = importlib.util.spec_from_file_location("gallery", ROOT / "scripts" / "gallery.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_experiment_has_a_gallery_entry_and_an_image_in_docs():
    figures = {p.stem for p in (ROOT / "conf" / "experiment").glob("fig*.yaml")}
    experiments = {p.stem for p in (ROOT / "conf" / "experiment").glob("*.yaml")}
    gallery = gallery_module().GALLERY
    assert figures <= set(gallery) <= experiments
    text = (ROOT / "docs" / "gallery.md").read_text()
    for name, (_, entries) in gallery.items():
        for n in range(len(entries)):
            assert f"(gallery/{name}__{n}.png)" in text
            assert (ROOT / "docs" / "gallery" / f"{name}__{n}.png").is_file()


def shipped_models() -> set[str]:
    return {p.stem for p in (ROOT / "conf" / "app").glob("*.yaml")
            if not p.stem.startswith("_") and "_target_: decrun.apps.model.Model" in p.read_text()}


def test_every_shipped_model_has_a_gallery_section_with_its_numbers():
    models = gallery_module().MODELS
    assert shipped_models() == {"brusselator", "cahn_hilliard", "darcy", "gray_scott", "halfar", "heat",
                                "heat_geodesics", "klausmeier", "mcf", "newton_cooling", "poisson", "shallow_water", "wave"}
    for model in shipped_models():
        assert any(name == f"model_{model}" or name.startswith(f"model_{model}_") for name in models), model
    text = (ROOT / "docs" / "gallery.md").read_text()
    for name, (_, entries) in models.items():
        section = text.split(f"## {name}\n", 1)[1].split("\n## ", 1)[0]
        for n, (overrides, _, shown, *_) in enumerate(entries):
            assert f"(gallery/{name}__{n}.png)" in section
            assert (ROOT / "docs" / "gallery" / f"{name}__{n}.png").is_file()
            note = next(line for line in section.splitlines() if line.startswith(f"- `decrun {' '.join(overrides)}`"))
            assert all(f"{key} = " in note for key in shown), (name, note)  # every number, from the run


def test_the_committed_page_is_the_one_the_tables_write():
    """docs/gallery.md holds no number of its own: it is written whole from GALLERY and MODELS,
    every number a placeholder of docs/numbers.json (tests/test_numbers.py reruns those runs)."""
    assert (ROOT / "docs" / "gallery.md").read_text() == gallery_module().page(), \
        "docs/gallery.md is not what scripts/gallery.py writes: run it (--only <section> reruns only those figures)"


def test_only_reruns_the_named_sections_and_writes_every_section(tmp_path):
    (tmp_path / "gallery.md").write_text("# Gallery\n\n## model_poisson\n\nold\n")
    text = gallery_module().build(tmp_path, ["model_poisson"]).read_text()
    assert text == gallery_module().page()
    poisson = text.split("## model_poisson\n", 1)[1]
    assert "old" not in poisson
    assert ("- `decrun app=poisson`: l2_error_rel = {{ numbers.gallery_model_poisson__0.l2_error_rel }},"
            in poisson)
    assert "## fig6_8_saddle\n" in text  # every section, its figure not rerun
    assert (tmp_path / "gallery" / "model_poisson__0.png").stat().st_size > 10_000
    assert not (tmp_path / "gallery" / "fig6_8_saddle__0.png").exists()  # not rerun


@pytest.mark.slow
def test_the_gallery_script_regenerates_every_figure(tmp_path):
    path = gallery_module().build(tmp_path)
    text = path.read_text()
    images = sorted((tmp_path / "gallery").glob("*.png"))
    module = gallery_module()
    assert len(images) == sum(len(e) for _, e in [*module.GALLERY.values(), *module.MODELS.values()])
    assert all(f"(gallery/{p.name})" in text for p in images)
    assert all(p.stat().st_size > 10_000 for p in images)  # drawn, not empty
