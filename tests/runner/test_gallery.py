"""The gallery (scripts/gallery.py → docs/gallery.md) shows every thesis-figure experiment
(conf/experiment/fig*.yaml) and the model experiments that have a picture (darcy_convergence);
the others — operator_variants, dt_crit_search — are tables."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


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


@pytest.mark.slow
def test_the_gallery_script_regenerates_every_figure(tmp_path):
    path = gallery_module().build(tmp_path)
    text = path.read_text()
    images = sorted((tmp_path / "gallery").glob("*.png"))
    assert len(images) == sum(len(e) for _, e in gallery_module().GALLERY.values())
    assert all(f"(gallery/{p.name})" in text for p in images)
    assert all(p.stat().st_size > 10_000 for p in images)  # drawn, not empty
