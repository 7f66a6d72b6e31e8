"""The reference plane fit of the detector's kernel tests: least squares by the SVD."""

from __future__ import annotations

import numpy as np


def svd_plane(P):
    """Least-squares plane of points (k, 3) by the SVD: unit normal towards the origin, offset."""
    c = P.mean(axis=0)
    n = np.linalg.svd(P - c, full_matrices=False)[2][-1]
    if n @ c > 0:
        n = -n
    return n, -n @ c
