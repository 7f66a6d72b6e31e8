"""Tests of reading articulation track files."""

from pathlib import Path

import numpy as np
import pytest

from mmlearn.models.common.track_io import TrackFileError, find_track_files, read_track

DATA = Path(__file__).parent / "data" / "articulation_logs"


def test_read_real_files():
    t = read_track(DATA / "drawer_001.log")
    assert t.poses.shape[1] == 3 and t.n > 200 and not t.has_orientation
    r = read_track(DATA / "rectangle_drawer.txt")
    assert r.poses.shape == (19, 7) and r.extra.shape == (19, 2) and r.has_orientation
    assert np.allclose(np.linalg.norm(r.poses[:, 3:], axis=1), 1.0)


def test_comments_and_seven_columns(tmp_path):
    p = tmp_path / "t.txt"
    p.write_text("# header\n0 0 0 0 0 0 1\n\n1 0 0 0 0 0 2  # trailing\n2 0 0 0 0 0 1\n")
    t = read_track(p)
    assert t.n == 3 and t.line_numbers.tolist() == [2, 4, 5]
    assert np.allclose(t.poses[1, 3:], [0, 0, 0, 1])


@pytest.mark.parametrize("text,match", [
    ("0 0 0\n1 1\n2 2 2\n", r"t\.log:2: expected 3, 7 or 9 columns"),
    ("0 0 0\n1 1 1\n2 nan 2\n", r"t\.log:3: NaN"),
    ("0 0 0\n1 1 1\n", r"only 2 observation"),
    ("0 0 0\n1 1 1 0 0 0 1\n2 2 2\n", r"t\.log:2: 7 columns, but earlier lines have 3"),
    ("0 0 0\n1 x 1\n2 2 2\n", r"t\.log:2: non-numeric"),
    ("0 0 0 0 0 0 0\n1 1 1 0 0 0 1\n2 2 2 0 0 0 1\n", r"t\.log:1: zero quaternion"),
])
def test_bad_files_name_file_and_line(tmp_path, text, match):
    p = tmp_path / "t.log"
    p.write_text(text)
    with pytest.raises(TrackFileError, match=match):
        read_track(p)


def test_missing_file_and_folder_expansion(tmp_path):
    with pytest.raises(TrackFileError, match="not found"):
        read_track(tmp_path / "nope.log")
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x.log").write_text("0 0 0\n")
    (tmp_path / "a" / "README.md").write_text("hi")
    files = find_track_files([tmp_path, tmp_path / "missing.log"])
    assert [Path(f).name for f in files] == ["x.log", "missing.log"]
