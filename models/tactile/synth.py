"""Synthetic ch. 6 tactile data for tests and benchmarks (not physics: the Drake tactile sensor
produces the real simulated data; this is a controllable stand-in with known ground truth).

An object is a stack of ``n_heights`` segments along its height; each segment has a contact
pattern on a 14 x 6 pad (a vertical bar of some thickness, a horizontal or diagonal edge, a
blob, a full flat contact, ...) and a width (m). A grasp at height index j returns the
segment's pattern shifted by a random -1..1 rows, scaled by a random pressure factor, plus
Gaussian noise, clipped to [0, 1]; the right pad sees the mirror image (columns reversed) with
its own noise; the finger distance is the segment's width plus noise.
"""

from __future__ import annotations

import numpy as np

from mmlearn.models.tactile.recognition import TactileSet, shift_rows

__all__ = ["pattern_bank", "make_objects", "sample_grasps"]

ROWS, COLS = 14, 6


def pattern_bank() -> np.ndarray:
    """(P, 14, 6) distinct noise-free contact patterns in [0, 1]."""
    pats = []
    r, c = np.mgrid[0:ROWS, 0:COLS]
    for t in (1, 2, 4):  # vertical bars of thickness t, centred
        pats.append(((c >= (COLS - t) // 2) & (c < (COLS - t) // 2 + t)).astype(float))
    for row in (3, 7, 10):  # horizontal lines
        pats.append((np.abs(r - row) <= 0).astype(float))
    for s in (1.5, -1.5, 3.0):  # diagonals
        pats.append((np.abs((r - ROWS / 2) - s * (c - COLS / 2)) < 1.0).astype(float))
    for rr, rad in ((4, 2.0), (9, 2.5), (7, 1.2)):  # blobs
        pats.append(np.clip(1.0 - ((r - rr) ** 2 + (c - 2.5) ** 2) / rad ** 2, 0, 1))
    pats.append(np.full((ROWS, COLS), 0.6))  # flat contact
    pats.append((r >= 7).astype(float) * 0.8)  # edge: lower half
    pats.append(((r + c) % 4 == 0).astype(float) * 0.7)  # texture
    return np.stack(pats)


def make_objects(n_classes: int, n_heights: int, *, rng, shared: float = 0.0) -> dict:
    """Random objects: {"pattern": (n_classes, n_heights) pattern ids, "width": (n_classes,
    n_heights) metres}. With ``shared`` in [0, 1), that fraction of the heights shows the
    same pattern and width on every object (like the thesis' industrial parts, which differ
    only in details)."""
    P = len(pattern_bank())
    pat = rng.integers(0, P, size=(n_classes, n_heights))
    wid = rng.uniform(0.02, 0.09, size=(n_classes, n_heights))
    n_sh = int(round(shared * n_heights))
    if n_sh:
        cols = rng.choice(n_heights, size=n_sh, replace=False)
        pat[:, cols] = rng.integers(0, P, size=n_sh)[None, :]
        wid[:, cols] = rng.uniform(0.02, 0.09, size=n_sh)[None, :]
    return {"pattern": pat, "width": wid}


def sample_grasps(objects: dict, classes, heights, *, rng, noise: float = 0.08,
                  width_noise: float = 0.002, height_step: float = 0.02,
                  names=None) -> TactileSet:
    """One grasp per (class index, height index) pair of the two sequences; heights in metres
    are ``height_index * height_step``."""
    classes = np.asarray(classes, dtype=int)
    heights = np.asarray(heights, dtype=int)
    bank = pattern_bank()
    img = bank[objects["pattern"][classes, heights]]
    img = img * rng.uniform(0.8, 1.2, size=(len(classes), 1, 1))
    taus = rng.integers(-1, 2, size=len(classes))
    left = np.stack([shift_rows(im, int(t)) for im, t in zip(img, taus)])
    right = left[:, :, ::-1].copy()
    left = np.clip(left + rng.normal(0, noise, left.shape), 0, 1)
    right = np.clip(right + rng.normal(0, noise, right.shape), 0, 1)
    w = objects["width"][classes, heights] + rng.normal(0, width_noise, len(classes))
    labels = np.array([f"obj{c}" if names is None else names[c] for c in classes], dtype=object)
    return TactileSet(left, right, heights * height_step, w, labels)
