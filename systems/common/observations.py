"""Value types carried on abstract-valued ports between mmlearn systems."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform


@dataclass
class MarkerObservations:
    """One frame of marker observations (the output of :class:`MarkerSensor`).

    Attributes:
        time: simulation time of the frame, seconds.
        marker_ids: name of each marker (the body that carries it), length m.
        poses: observed pose of each marker in the world (camera-corrected) frame,
            ``RigidTransform`` X_WM, length m. For an invisible marker the entry holds the
            last value drawn by the noise model and must not be used.
        visible: bool array (m,), True where the marker was seen in this frame.
        outlier: bool array (m,), True where the pose is a uniform outlier (ground truth,
            for evaluation only; a learner must not read it).
    """

    time: float = 0.0
    marker_ids: list[str] = field(default_factory=list)
    poses: list[RigidTransform] = field(default_factory=list)
    visible: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    outlier: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def __len__(self) -> int:
        return len(self.marker_ids)

    def index(self, marker_id: str) -> int:
        """Index of ``marker_id``; raises KeyError naming the known ids."""
        try:
            return self.marker_ids.index(marker_id)
        except ValueError:
            raise KeyError(
                f"marker {marker_id!r} not in this frame; known: {self.marker_ids}"
            ) from None

    def pose(self, marker_id: str) -> RigidTransform | None:
        """Observed pose of ``marker_id``, or None when it was not visible."""
        i = self.index(marker_id)
        return self.poses[i] if bool(self.visible[i]) else None

    def as_array(self) -> np.ndarray:
        """Poses as an (m, 7) array ``x y z qx qy qz qw``; rows of invisible markers are NaN."""
        out = np.full((len(self.marker_ids), 7), np.nan)
        for i, X in enumerate(self.poses):
            if bool(self.visible[i]):
                q = X.rotation().ToQuaternion()
                out[i, :3] = X.translation()
                out[i, 3:] = (q.x(), q.y(), q.z(), q.w())
        return out

    def as_matrices(self) -> np.ndarray:
        """Poses as an (m, 4, 4) array; matrices of invisible markers are NaN."""
        out = np.full((len(self.marker_ids), 4, 4), np.nan)
        for i, X in enumerate(self.poses):
            if bool(self.visible[i]):
                out[i] = X.GetAsMatrix4()
        return out
