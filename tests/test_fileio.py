"""mmlearn.models.common.fileio: the atomic text write used for results and summaries."""

import os
import stat

import pytest

from mmlearn.models.common.fileio import atomic_write_text


def test_atomic_write_replaces_the_file_whole(tmp_path):
    path = atomic_write_text(tmp_path / "sub" / "out.json", "first\n")
    assert path.read_text() == "first\n"
    atomic_write_text(path, "second\n")
    assert path.read_text() == "second\n"
    assert sorted(p.name for p in path.parent.iterdir()) == ["out.json"]  # no temporary left
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


def test_atomic_write_keeps_the_old_file_when_writing_fails(tmp_path):
    path = atomic_write_text(tmp_path / "out.txt", "kept\n")

    class Unwritable:
        pass

    with pytest.raises(TypeError):
        atomic_write_text(path, Unwritable())
    assert path.read_text() == "kept\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]
