"""The one temp-file-then-rename helper every runner file write goes through."""

from __future__ import annotations

import os

import pytest

from decrun.runner.io.atomic import atomic_path, temporary_name, write_text_atomic


def test_the_file_appears_whole_under_its_name_only_when_the_block_ends(tmp_path):
    path = tmp_path / "metrics.json"
    path.write_text("old")
    with atomic_path(path) as tmp:
        assert tmp == temporary_name(path) == tmp_path / f".metrics.json.tmp-{os.getpid()}"
        tmp.write_text("new")
        assert path.read_text() == "old"  # readers still see the old file
    assert path.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["metrics.json"]


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "manifest.json"
    path.write_text("old")
    with pytest.raises(RuntimeError, match="disk"):
        with atomic_path(path) as tmp:
            tmp.write_text("half")
            raise RuntimeError("disk full")
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["manifest.json"]


def test_write_text_atomic_and_a_rename_that_fails(tmp_path):
    assert write_text_atomic(tmp_path / "a.md", "| x |\n").read_text() == "| x |\n"
    (tmp_path / "dir").mkdir()
    with pytest.raises(OSError):  # a directory where the file should go: the rename fails
        write_text_atomic(tmp_path / "dir", "text")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.md", "dir"]
