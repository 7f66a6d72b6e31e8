"""The front detector's label masks (Eq. 5.2): in-plane, occluded, free and unknown pixels,
and the surface check that keeps a tilted fit's surface but removes a step behind it."""

import numpy as np

from mmlearn.models.perception.detection import Plane
from mmlearn.models.perception.detection.labels import (FREE, IN_PLANE, OCCLUDED, OFF_SURFACE,
                                                        UNKNOWN, _label_images, _surface_check)


def test_mask_labels_follow_eq_5_2():
    """Plane z = 2 m facing the camera: a pixel in front of it is occluded, behind it free,
    within L in-plane, without a measurement unknown."""
    d = np.array([[1.5, 2.0, 2.5, 0.0]], np.float32)
    valid = np.array([[True, True, True, False]])
    ray = np.zeros((1, 4), np.float32)
    lab = _label_images(d, valid, ray, ray, [Plane(n=np.array([0, 0, -1.0]), d=2.0, support=1)],
                        np.float32(0.02), 20.0)[0]
    assert lab.tolist() == [[OCCLUDED, IN_PLANE, FREE, UNKNOWN]]


def test_surface_check_tolerates_a_tilted_plane_fit_but_removes_a_step():
    """Handle regression (sliding_door seed 1 gave 0.154 m): the plane fitted to a 0.5 m panel
    1.7 deg off departs from its sides by ~7 mm; the surface check must keep those pixels
    (it once removed half the panel with its handle) and still remove a strip 8 mm behind
    the surrounding surface (the edge face of a panel seen obliquely)."""
    rng = np.random.default_rng(0)
    H, W = 120, 300
    S = np.tile(np.linspace(-0.007, 0.007, W, dtype=np.float32), (H, 1))  # tilted fit
    S += rng.normal(0.0, 0.002, (H, W)).astype(np.float32)
    S[:, 200:206] += np.float32(0.008)                                   # a 6 px step
    lab = np.full((H, W), IN_PLANE, np.uint8)
    Lm = np.full((H, W), 0.003, np.float32)
    _surface_check(lab, S, Lm, 5)
    gone = lab == OFF_SURFACE
    strip = np.zeros((H, W), bool)
    strip[10:-10, 200:206] = True
    ramp = np.zeros((H, W), bool)
    ramp[10:-10, 10:190] = True
    assert gone[ramp].mean() < 0.01, gone[ramp].mean()
    assert gone[strip].mean() > 0.8, gone[strip].mean()
