"""mmlearn.models.common.fileio: checked output paths (a probe write) and atomic writes."""

import os
import stat

import numpy as np
import pytest

from mmlearn.models.common.fileio import (OutputPathError, atomic_output, atomic_write_bytes,
                                          atomic_write_text, check_output_dir,
                                          check_output_file)

# a folder that os.access calls writable for root, but where nothing can be created
UNWRITABLE = next((d for d in ("/sys/kernel", "/proc") if os.path.isdir(d)
                   and os.access(d, os.W_OK)), None)


def test_atomic_write_replaces_the_file_whole(tmp_path):
    path = atomic_write_text(tmp_path / "out.json", "first\n")
    assert path.read_text() == "first\n"
    atomic_write_text(path, "second\n")
    assert path.read_text() == "second\n"
    assert sorted(p.name for p in path.parent.iterdir()) == ["out.json"]  # no temporary left
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


def test_a_missing_folder_is_an_error_unless_asked_to_create_it(tmp_path):
    with pytest.raises(OutputPathError, match=r"folder .*sub does not exist"):
        atomic_write_text(tmp_path / "sub" / "out.json", "x")
    assert not (tmp_path / "sub").exists()
    path = atomic_write_text(tmp_path / "sub" / "deeper" / "out.json", "x", create_dirs=True)
    assert path.read_text() == "x"


def test_atomic_write_keeps_the_old_file_when_writing_fails(tmp_path):
    path = atomic_write_text(tmp_path / "out.txt", "kept\n")

    class Unwritable:
        pass

    with pytest.raises(TypeError):
        atomic_write_text(path, Unwritable())
    with pytest.raises(RuntimeError):
        with atomic_output(path) as f:
            f.write(b"half")
            raise RuntimeError("interrupted")
    assert path.read_text() == "kept\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_atomic_output_takes_file_object_writers(tmp_path):
    a = np.arange(6.0).reshape(2, 3)
    with atomic_output(tmp_path / "a.npy") as f:
        np.save(f, a)
    assert np.array_equal(np.load(tmp_path / "a.npy"), a)
    atomic_write_bytes(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"


def test_check_output_file_names_the_flag_and_the_path(tmp_path):
    (tmp_path / "f").write_text("")
    assert check_output_file(tmp_path / "ok.png", what="--plot") == tmp_path / "ok.png"
    assert not (tmp_path / "ok.png").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]  # the probe is removed
    cases = [(tmp_path, "is a folder, expected a file name"),
             (tmp_path / "f" / "x.png", "f is a file, not a folder"),
             (tmp_path / "no" / "x.png", "no does not exist \\(create it, or pass --create-dirs\\)")]
    for path, msg in cases:
        with pytest.raises(OutputPathError, match=f"^--plot: .*{msg}"):
            check_output_file(path, what="--plot", flag_hint="--create-dirs")
    check_output_file(tmp_path / "no" / "x.png", create_dirs=True)
    assert (tmp_path / "no").is_dir()
    assert check_output_file(None) is None and check_output_file("") is None


def test_check_output_dir(tmp_path):
    (tmp_path / "f").write_text("")
    assert check_output_dir(tmp_path / "new", what="--out-dir").is_dir()
    with pytest.raises(OutputPathError, match="^--out-dir: .*f is a file, expected a folder"):
        check_output_dir(tmp_path / "f", what="--out-dir")
    with pytest.raises(OutputPathError, match="folder .*a does not exist"):
        check_output_dir(tmp_path / "a" / "b", what="--out-dir")
    with pytest.raises(OutputPathError, match="folder .*c does not exist"):
        check_output_dir(tmp_path / "c", what="--out-dir", create=False)
    assert check_output_dir(tmp_path / "a" / "b", create_dirs=True).is_dir()


@pytest.mark.skipif(UNWRITABLE is None, reason="needs a folder os.access calls writable")
def test_an_unwritable_folder_is_found_by_writing_not_by_os_access():
    with pytest.raises(OutputPathError, match=f"^--html-out: cannot write in folder {UNWRITABLE}"):
        check_output_file(os.path.join(UNWRITABLE, "x.html"), what="--html-out")
    with pytest.raises(OutputPathError, match=f"^--out-dir: cannot write in folder {UNWRITABLE}"):
        check_output_dir(UNWRITABLE, what="--out-dir")
