"""How a cabinet front moves: a stepped opening profile along its joint and the true pose of
the front's outer face as a function of the joint value (plain numpy, thesis ch. 5 scenes).

The thesis' kinematic-learning logs (5.2.2) open a door and a drawer repeatedly; the scene of
:mod:`mmlearn.diagrams.perception.diagram` opens the moving front in ``steps`` equal moves with pauses
between them (a staircase of the joint value: linear ramps and holds), optionally closing it
again the same way.
"""


import math
from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.config import param, validate_fields

__all__ = ["FrontMotionConfig", "stepped_profile", "FrontJointKinematics"]


@dataclass
class FrontMotionConfig:
    """The moving front's joint trajectory (load with ``yaml_load_typed``).

    Attributes:
        door_opening_deg: how far the door opens in the end, deg (thesis: up to ~90).
        drawer_opening: how far the drawer is pulled out in the end, m (up to ~0.3).
        steps: number of equal opening moves (>= 1).
        step_time: duration of one move, s (> 0).
        hold_time: pause before the first move and after every move, s (>= 0).
        close_again: after opening, close in the same steps.
    """

    door_opening_deg: float = param(90.0, unit="deg", ge=0)
    drawer_opening: float = param(0.30, unit="m", ge=0)
    steps: int = param(6, integer=True, ge=1)
    step_time: float = param(1.0, unit="s", gt=0)
    hold_time: float = param(1.0, unit="s", ge=0)
    close_again: bool = False

    def validate(self) -> "FrontMotionConfig":
        """Raise ``ValueError`` naming the first bad field; return the config."""
        return validate_fields(self)

    def opening(self, front: str) -> float:
        """Final joint value of the moving front: rad for the door, m for the drawer."""
        if front == "door":
            return math.radians(self.door_opening_deg)
        if front == "drawer":
            return float(self.drawer_opening)
        raise ValueError(f"front must be 'door' or 'drawer', got {front!r}")

    def duration(self) -> float:
        """Length of the whole profile, s."""
        n = self.steps * (2 if self.close_again else 1)
        return self.hold_time + n * (self.step_time + self.hold_time)


def stepped_profile(opening: float, config: FrontMotionConfig) -> tuple[np.ndarray, np.ndarray]:
    """Knots (times (n,), s; values (n,), rad or m) of the piecewise-linear staircase from 0
    to ``opening`` (and back with ``close_again``). Hold segments of zero length are left out
    so the times strictly increase."""
    config.validate()
    if not math.isfinite(opening):
        raise ValueError(f"stepped_profile: opening must be finite, got {opening}")
    levels = [opening * k / config.steps for k in range(1, config.steps + 1)]
    if config.close_again:
        levels += [opening * k / config.steps for k in range(config.steps - 1, -1, -1)]
    t, q = [0.0], [0.0]
    if config.hold_time > 0:
        t.append(config.hold_time)
        q.append(0.0)
    for lv in levels:
        t.append(t[-1] + config.step_time)
        q.append(lv)
        if config.hold_time > 0:
            t.append(t[-1] + config.hold_time)
            q.append(lv)
    return np.asarray(t), np.asarray(q)


def _rotations(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations by ``angles`` (rad) about the unit ``axis`` (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3) + s * Kx + (1 - c) * (Kx @ Kx)


@dataclass(frozen=True)
class FrontJointKinematics:
    """The pose of a front's outer face as a function of its joint value.

    Attributes:
        kind: "revolute" or "prismatic".
        axis_W: (3,) joint axis in the world (unit; positive q opens).
        point_W: (3,) a point on the hinge line (revolute), m; ignored for prismatic.
        X_WR0: (4, 4) the face pose at q = 0 (FrontRectangle axes: x along the width, y
            along the height, z the outward normal).
        width, height: the front's size, m.
    """

    kind: str
    axis_W: np.ndarray
    point_W: np.ndarray
    X_WR0: np.ndarray
    width: float
    height: float

    def __post_init__(self):
        if self.kind not in ("revolute", "prismatic"):
            raise ValueError(f"FrontJointKinematics.kind must be revolute or prismatic, got "
                             f"{self.kind!r}")
        a = np.asarray(self.axis_W, float).reshape(3)
        if not np.isfinite(a).all() or np.linalg.norm(a) < 1e-9:
            raise ValueError("FrontJointKinematics.axis_W must be a finite non-zero 3-vector")
        object.__setattr__(self, "axis_W", a / np.linalg.norm(a))
        object.__setattr__(self, "point_W", np.asarray(self.point_W, float).reshape(3))
        X = np.asarray(self.X_WR0, float)
        if X.shape != (4, 4) or not np.isfinite(X).all():
            raise ValueError("FrontJointKinematics.X_WR0 must be a finite 4x4 matrix")
        object.__setattr__(self, "X_WR0", X)

    def X_WR(self, q) -> np.ndarray:
        """Face poses for joint values ``q`` (rad or m): (4, 4) for a scalar, else (n, 4, 4)."""
        qa = np.asarray(q, float)
        scalar = qa.ndim == 0
        qa = qa.reshape(-1)
        n = qa.size
        out = np.tile(self.X_WR0, (n, 1, 1))
        if self.kind == "revolute":
            R = _rotations(self.axis_W, qa)
            out[:, :3, :3] = R @ self.X_WR0[:3, :3]
            out[:, :3, 3] = self.point_W + (R @ (self.X_WR0[:3, 3] - self.point_W))
        else:
            out[:, :3, 3] = self.X_WR0[:3, 3] + qa[:, None] * self.axis_W
        return out[0] if scalar else out
