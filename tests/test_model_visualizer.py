import base64
import re

import numpy as np
import pytest
from pydrake.geometry import StartMeshcat

from mmlearn.apps import open_cabinet
from mmlearn.models.articulation import ObservationModel, make_model
from mmlearn.systems import LearnedModelVisualizer


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


def test_recording_of_a_trial_contains_the_learned_model(tmp_path):
    html = tmp_path / "drawer.html"
    r = open_cabinet.run(kind="drawer", seed=2, html_out=str(html), show_progress=False)
    assert r["success"] and r["html_out"] == str(html)
    blobs = re.findall(r"base64,([A-Za-z0-9+/=]+)", html.read_text())
    decoded = b"".join(base64.b64decode(b) for b in blobs)
    for name in (b"learned_model", b"mechanism", b"hook"):
        assert name in decoded, name
