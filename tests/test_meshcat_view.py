"""The legend panel and the scene legends of the recordings (quick: no simulation)."""

from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image
from pydrake.geometry import Rgba, StartMeshcat

from mmlearn.models.articulation.link import ObservationModel, make_model
from mmlearn.models.imitation.types import TaskModel
from mmlearn.diagrams.imitation.diagram import ellipsoid_stride
from mmlearn.systems.common.meshcat_view import LEGEND_KINDS, LEGEND_PATH, _legend_png, \
    draw_legend
from mmlearn.systems.perception.front_visualizer import front_legend, track_colour


def test_legend_image_fits_its_text_and_draws_every_swatch(tmp_path):
    rows = [(Rgba(0.9, 0.1, 0.1, 1), k, f"a row of kind {k!r}") for k in LEGEND_KINDS]
    w, h = _legend_png(tmp_path / "a.png", "Title", rows)
    assert h == 40 * (len(rows) + 1) + 12 and w == 620  # the least width
    long = rows + [(None, "", "x" * 120)]
    w2, _ = _legend_png(tmp_path / "b.png", "Title", long)
    assert w2 > w  # grows with its longest row
    img = np.asarray(Image.open(tmp_path / "a.png").convert("RGB")).astype(int)
    red = (img[..., 0] > 180) & (img[..., 1] < 90)
    # every row with a swatch kind has red pixels in the swatch column (x < 75)
    for i, (_, kind, _) in enumerate(rows):
        y = 6 + 40 * (i + 1)
        assert red[y:y + 40, :75].any() == bool(kind), kind
    with pytest.raises(ValueError, match="legend row kind"):
        _legend_png(tmp_path / "c.png", "T", [(Rgba(0, 0, 0, 1), "arrow", "x")])


def test_draw_legend_puts_the_panel_under_the_camera():
    mc = StartMeshcat()
    draw_legend(mc, "A legend", [(Rgba(0.1, 0.4, 1, 1), "line", "something drawn")])
    assert mc.HasPath(LEGEND_PATH) and LEGEND_PATH.startswith("/Cameras/default/")


def _link(name, track):
    return make_model(name, obs=ObservationModel(sigma_pos=0.005)).fit(track, rng=0)


def test_front_legend_names_the_moving_track_and_the_others():
    a = np.linspace(0.0, 1.0, 30)
    door = _link("revolute", np.c_[0.4 * np.cos(a), 0.4 * np.sin(a), np.full(30, 0.7)])
    still = _link("rigid", np.tile([0.1, 0.2, 0.3], (10, 1)))
    tracks = [SimpleNamespace(track_id=k, n=n) for k, n in ((3, 25), (1, 9), (4, 7))]
    models = {3: SimpleNamespace(model=door), 1: SimpleNamespace(model=still),
              4: SimpleNamespace(model=still)}
    title, rows = front_legend("door", 3, tracks, models)
    texts = [t for _, _, t in rows]
    assert title.startswith("Front perception")
    assert texts[0] == f"moving door's track 3 (25 detections): learned revolute, " \
                       f"radius {door.radius:.2f} m"
    assert rows[0][0].g() == track_colour(3).g()  # in the track's colour
    span = np.degrees(door.q_max[0] - door.q_min[0])
    assert f"  span of its track on the model ({span:.0f} deg)" in texts
    assert "2 other tracks (one colour each; learned: 2 rigid)" in texts
    assert "noisy depth points of that frame" in texts
    _, rows = front_legend("drawer", None, tracks, models, point_cloud=False)
    texts = [t for _, _, t in rows]
    assert texts[0] == "the moving drawer was not tracked"
    assert "noisy depth points of that frame" not in texts


def test_ellipsoid_stride_draws_about_a_dozen():
    for S in (5, 12, 40, 200):
        m = TaskModel(t=np.arange(S) * 0.2, constraints=["obj:cup"],
                      mean={"obj:cup": np.zeros((S, 3))}, var={"obj:cup": np.ones((S, 3))})
        k = ellipsoid_stride(m)
        n = len(range(0, S, k))
        assert k >= 1 and (8 <= n <= 18 if S >= 12 else n == S), (S, k)


def test_make_screenshots_names_a_bad_choice(capsys):
    """docs/make_screenshots.py: one screenshot per capability; an unknown name is bad input
    (exit 2, one line naming it and the known ones) before anything runs."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "docs" / "make_screenshots.py"
    spec = importlib.util.spec_from_file_location("make_screenshots", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert set(mod.SHOTS) == {"door", "drawer", "fronts", "body_schema", "imitation",
                              "tactile"}
    assert mod.main(["--only", "door,nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--only: unknown nope" in err[0] and "body_schema" in err[0]
