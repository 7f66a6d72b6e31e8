import base64
import re

import numpy as np
import pytest
from pydrake.geometry import StartMeshcat

from headless_browser import chromium, screenshot_or_skip
from mmlearn.apps import open_cabinet
from mmlearn.apps.common.cli import frame_camera
from mmlearn.models.articulation.link import ObservationModel, make_model
from mmlearn.systems import LearnedModelVisualizer
from mmlearn.systems.articulation.model_visualizer import LEGEND_PATH, legend_entries


@pytest.fixture(scope="module")
def meshcat():
    return StartMeshcat()


def _arc(n=40):
    a = np.linspace(0, 1.2, n)
    return np.c_[0.4 * np.cos(a), 0.4 * np.sin(a), np.full(n, 0.7)]


@pytest.mark.parametrize("name,track,paths", [
    ("revolute", _arc(), ["axis", "range", "circle", "center"]),
    ("prismatic", np.c_[np.linspace(0, 0.4, 30), np.zeros(30), np.full(30, 0.7)],
     ["axis", "range"]),
    ("rigid", np.tile([0.1, 0.2, 0.3], (10, 1)), ["position"]),
])
def test_draws_each_kind_of_model(meshcat, name, track, paths):
    vis = LearnedModelVisualizer(meshcat=meshcat, prefix=f"test_{name}")
    link = make_model(name, obs=ObservationModel(sigma_pos=0.01)).fit(track, rng=0)
    vis.draw(link)
    for p in paths:
        assert meshcat.HasPath(f"test_{name}/{p}"), p
    vis.draw(None)
    assert not meshcat.HasPath(f"test_{name}/{paths[0]}")


def test_legend_names_what_is_drawn(meshcat):
    """The legend's rows, in the drawing's colours, for each kind of model; draw() puts the
    legend (a textured quad) at legend_path, also for "no model yet"."""
    rev = make_model("revolute", obs=ObservationModel(sigma_pos=0.01)).fit(_arc(), rng=0)
    title, rows = legend_entries(rev)
    assert title == "Learned model: revolute"
    texts = [t for _, _, t in rows]
    assert texts[0] == "learned rotation axis"
    assert texts[1] == f"learned circle (radius {rev.radius:.2f} m)"
    span = [t for t in texts if t.startswith("span of the track it was fitted to (")]
    assert len(span) == 1 and f" deg, {rev.n_train} observations)" in span[0]
    colours = {t: c for c, _, t in rows}
    assert colours["learned rotation axis"].r() == pytest.approx(0.1)  # the axis's blue
    assert colours[texts[3]].r() == pytest.approx(1.0)  # the range's red
    pri = make_model("prismatic", obs=ObservationModel(sigma_pos=0.01)).fit(
        np.c_[np.linspace(0, 0.4, 30), np.zeros(30), np.full(30, 0.7)], rng=0)
    assert [t for _, _, t in legend_entries(pri)[1]][0] == "learned prismatic axis"
    assert legend_entries(None)[0] == "Learned model: none yet"
    vis = LearnedModelVisualizer(meshcat=meshcat, prefix="legend_test",
                                 legend_path="legend_test_legend")
    for link in (None, rev, pri):
        vis.draw(link)
        assert meshcat.HasPath("legend_test_legend")
    assert LEGEND_PATH.startswith("/Cameras/default/rotated/<object>/")  # moves with the view


def test_frame_camera_sees_every_point():
    """frame_camera: every point projects inside a 75 deg x 4:3 view, tightly (the
    farthest-out point on the edge), looking along -view_from at the view's centre."""
    class Fake:
        def SetCameraPose(self, camera, target):
            self.camera, self.target = np.asarray(camera), np.asarray(target)

    rng = np.random.default_rng(0)
    P = rng.uniform([-0.5, -0.5, 0], [1.5, 0.5, 1.3], (40, 3))
    fake = Fake()
    view_from = np.array([1.8, 1.2, 0.9])
    cam, target = frame_camera(fake, P, view_from=view_from, margin=1.0)
    assert np.allclose(fake.camera, cam) and np.allclose(fake.target, target)
    f = (target - cam) / np.linalg.norm(target - cam)
    assert np.allclose(-f, view_from / np.linalg.norm(view_from))
    right = np.cross(f, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    depth = (P - cam) @ f
    x, y = (P - cam) @ right / depth, (P - cam) @ up / depth
    ty = np.tan(np.radians(37.5))
    worst = max(np.abs(x).max() / (ty * 4 / 3), np.abs(y).max() / ty)
    assert np.all(depth > 0) and 0.95 < worst <= 1.0 + 1e-6
    # centred: the outermost points are about equally far from opposite edges (exactly on
    # them in the direction that sets the distance)
    assert abs(x.max() + x.min()) < 0.1 * ty * 4 / 3 and abs(y.max() + y.min()) < 0.1 * ty


@pytest.fixture(scope="module")
def drawer_recording(tmp_path_factory):
    html = tmp_path_factory.mktemp("rec") / "drawer.html"
    r = open_cabinet.run(kind="drawer", seed=2, html_out=str(html), show_progress=False)
    return r, html


def _messages(html):
    blobs = re.findall(r"base64,([A-Za-z0-9+/=]+)", html.read_text())
    return b"".join(base64.b64decode(b) for b in blobs)


@pytest.mark.slow
def test_recording_of_a_trial_contains_the_learned_model(drawer_recording):
    r, html = drawer_recording
    assert r["success"] and r["html_out"] == str(html)
    decoded = _messages(html)
    for name in (b"learned_model", b"mechanism", b"hook"):
        assert name in decoded, name


@pytest.mark.slow
def test_recording_has_a_legend_and_a_camera(drawer_recording):
    """The recording's HTML carries the legend (under the camera, with its texture and
    its text) and the camera framing the robot and the cabinet (position and target)."""
    _, html = drawer_recording
    decoded = _messages(html)
    assert LEGEND_PATH.encode() in decoded
    for text in (b"# mmlearn legend: Learned model: prismatic", b"# learned prismatic axis",
                 b"# span of the track it was fitted to (", b"legend.png"):
        assert text in decoded, text
    # the camera: Meshcat.SetCameraPose = the camera's position and a set_target
    assert b"set_target" in decoded
    i = decoded.find(b"/Cameras/default/rotated/<object>\xa8property\xa8position")
    assert i >= 0, "no camera position in the recording"


@pytest.mark.slow
def test_recording_shows_the_legend_robot_and_cabinet_in_a_browser(drawer_recording):
    """Rendered in a real headless browser (800 x 600), the recording shows the legend panel
    in the top-left corner (light panel, dark text, the red swatch of the opening range) and,
    through the camera, the robot (orange arm, blue base) and the cabinet (light wood)."""
    browser = chromium()
    if browser is None:
        pytest.skip("no chromium on this machine (.ci/run installs Debian's chromium)")
    cv2 = pytest.importorskip("cv2")
    _, html = drawer_recording
    png = html.with_suffix(".png")
    screenshot_or_skip(browser, html, png)
    img = cv2.imread(str(png)).astype(int)
    b, g, r = img[..., 0], img[..., 1], img[..., 2]
    # the legend: top-left (x 94-410, y 12-80 px at 800 x 600, see model_visualizer)
    box = (slice(0, 110), slice(60, 460))
    panel = (np.abs(r - g) < 6) & (np.abs(g - b) < 6) & (r > 200)
    text = (r < 110) & (g < 110) & (b < 110)
    red = (r > 180) & (g < 110) & (b < 110)
    assert panel[box].sum() > 8000, f"no legend panel ({panel[box].sum()} light pixels)"
    assert text[box].sum() > 200, f"no legend text ({text[box].sum()} dark pixels)"
    assert red[box].sum() > 20, f"no red swatch in the legend ({red[box].sum()} pixels)"
    # the scene, framed by the camera: the arm, the base and the cabinet are in view
    orange = (r > 170) & (g > 80) & (g < 190) & (b < 80) & (r - g > 50)
    wood = (r > 180) & (g > 150) & (b > 90) & (b < 200) & (r - b > 40)
    blue_base = (b > 90) & (b - r > 40) & (g < 130)
    assert orange.sum() > 1000, f"arm not visible ({orange.sum()} orange pixels)"
    assert wood.sum() > 3000, f"cabinet not visible ({wood.sum()} wood pixels)"
    assert blue_base.sum() > 3000, f"base not visible ({blue_base.sum()} blue pixels)"
