"""A small pure-numpy simulated serial/tree arm with marker observations (thesis Sec. 3.4).

Used to test and benchmark body-schema learning without Drake. Every body part carries one
marker whose frame is the part frame. A part ``p`` hangs from its parent part through

    x_p = x_parent @ A_p @ J_p(q_a) @ B_p

where ``A_p`` and ``B_p`` are fixed transforms and ``J_p`` is a revolute (rotation about a unit
axis, radians) or prismatic (translation along a unit axis, metres) joint driven by *actual*
joint value ``q_a`` of action signal ``a``, or the identity for a rigid connection.

The *commanded* action vector is what the learner sees; failures make the actual joint values
or the geometry differ from the command:

* ``blocked``: {action index: stuck value}, that joint ignores its command.
* ``tool``: replaces the transform ``B`` of the tool part (e.g. a different tool length/angle).
* ``bend``: {part index: 4x4} extra transform inserted after ``B`` of that part (bent link).

Units: metres and radians. Poses are (4, 4) homogeneous matrices in the world frame; the base
part is at the identity.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mmlearn.models.common.se3 import rotvec_to_matrix

__all__ = [
    "ArmPart",
    "SimArm",
    "make_arm_2dof",
    "make_arm_4dof",
    "make_arm_7dof",
    "rot",
    "trans",
]


def rot(axis, angle) -> np.ndarray:
    """(..., 4, 4) rotation(s) about a unit ``axis`` by ``angle`` (radians, scalar or array)."""
    axis = np.asarray(axis, float)
    axis = axis / np.linalg.norm(axis)
    angle = np.asarray(angle, float)
    c, s = np.cos(angle), np.sin(angle)
    x, y, z = axis
    C = 1.0 - c
    T = np.zeros(angle.shape + (4, 4))
    T[..., 0, 0] = c + x * x * C
    T[..., 0, 1] = x * y * C - z * s
    T[..., 0, 2] = x * z * C + y * s
    T[..., 1, 0] = y * x * C + z * s
    T[..., 1, 1] = c + y * y * C
    T[..., 1, 2] = y * z * C - x * s
    T[..., 2, 0] = z * x * C - y * s
    T[..., 2, 1] = z * y * C + x * s
    T[..., 2, 2] = c + z * z * C
    T[..., 3, 3] = 1.0
    return T


def trans(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    """(4, 4) translation by (x, y, z) metres."""
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


@dataclass
class ArmPart:
    """One body part. ``joint`` is "rigid", "revolute" or "prismatic"; ``action`` its signal."""

    name: str
    parent: int | None
    A: np.ndarray = field(default_factory=lambda: np.eye(4))
    joint: str = "rigid"
    action: int | None = None
    axis: tuple = (0.0, 0.0, 1.0)
    B: np.ndarray = field(default_factory=lambda: np.eye(4))


@dataclass
class SimArm:
    """Simulated arm: forward kinematics, noisy marker observations and failures.

    Args:
        parts: body parts in topological order (parents first); part 0 is the base.
        action_low, action_high: (m,) sampling range of the commanded actions (rad or m).
        tool_part: index of the part whose ``B`` a tool change replaces (or None).
    """

    parts: list
    action_low: np.ndarray
    action_high: np.ndarray
    tool_part: int | None = None
    blocked: dict = field(default_factory=dict)
    tool: np.ndarray | None = None
    bend: dict = field(default_factory=dict)

    def __post_init__(self):
        self.action_low = np.asarray(self.action_low, float)
        self.action_high = np.asarray(self.action_high, float)
        for p, part in enumerate(self.parts):
            if part.parent is not None and not 0 <= part.parent < p:
                raise ValueError(f"part {p} ({part.name}): parent must come before it")

    @property
    def n_parts(self) -> int:
        return len(self.parts)

    @property
    def n_actions(self) -> int:
        return len(self.action_low)

    # ------------------------------------------------------------------ failures
    def block_joint(self, action: int, value: float) -> None:
        """Joint ``action`` sticks at ``value`` (rad or m) whatever is commanded."""
        self.blocked[int(action)] = float(value)

    def unblock_joint(self, action: int) -> None:
        self.blocked.pop(int(action), None)

    def change_tool(self, length: float, angle: float = 0.0, axis=(0.0, 1.0, 0.0)) -> None:
        """Replace the tool transform of ``tool_part``: ``rot(axis, angle) @ trans(z=length)``."""
        if self.tool_part is None:
            raise ValueError("this arm has no tool_part")
        self.tool = rot(axis, angle) @ trans(z=length)

    def reset_tool(self) -> None:
        self.tool = None

    def bend_link(self, part: int, angle: float = np.pi / 4, axis=(1.0, 0.0, 0.0)) -> None:
        """Bend the link of ``part`` by ``angle`` radians about ``axis`` (after its ``B``)."""
        self.bend[int(part)] = rot(axis, angle)

    def unbend(self) -> None:
        self.bend.clear()

    # ------------------------------------------------------------------ kinematics
    def sample_actions(self, n: int, rng) -> np.ndarray:
        """(n, m) uniformly random commanded actions ("motor babbling")."""
        rng = np.random.default_rng(rng)
        return rng.uniform(self.action_low, self.action_high, size=(n, self.n_actions))

    def forward(self, actions) -> np.ndarray:
        """True part poses (n, p, 4, 4) for commanded actions (n, m) (or (m,) -> (p, 4, 4))."""
        actions = np.asarray(actions, float)
        single = actions.ndim == 1
        actions = np.atleast_2d(actions)
        if actions.shape[1] != self.n_actions:
            raise ValueError(f"actions must have {self.n_actions} columns, got {actions.shape}")
        if not np.all(np.isfinite(actions)):
            raise ValueError("actions contain NaN or inf")
        n = actions.shape[0]
        q = actions.copy()
        for a, v in self.blocked.items():
            q[:, a] = v
        X = np.empty((n, self.n_parts, 4, 4))
        for p, part in enumerate(self.parts):
            if part.parent is None:
                T = np.broadcast_to(part.A, (n, 4, 4))
            else:
                T = X[:, part.parent] @ part.A
            if part.joint == "revolute":
                T = T @ rot(part.axis, q[:, part.action])
            elif part.joint == "prismatic":
                J = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
                J[:, :3, 3] = np.outer(q[:, part.action], np.asarray(part.axis, float))
                T = T @ J
            B = self.tool if (p == self.tool_part and self.tool is not None) else part.B
            T = T @ B
            if p in self.bend:
                T = T @ self.bend[p]
            X[:, p] = T
        return X[0] if single else X

    def observe(self, actions, rng, *, sigma_pos: float = 0.0, sigma_orient: float = 0.0,
                visibility: float = 1.0, occluded=(), outlier_rate: float = 0.0):
        """Noisy marker observations of the part poses.

        Args:
            actions: (n, m) commanded actions.
            rng: numpy Generator or seed.
            sigma_pos: RMS 3-D position error of a marker (m); per-axis std sigma_pos/sqrt(3).
            sigma_orient: RMS 3-D orientation error (rad) (rotation vector, per-axis /sqrt(3)).
            visibility: probability that a marker is seen in a frame.
            occluded: part indices that are never observed.
        Returns:
            (Y, X): observed poses (n, p, 4, 4) with NaN for unseen markers, true poses.
        """
        rng = np.random.default_rng(rng)
        X = self.forward(np.atleast_2d(actions))
        n, p = X.shape[:2]
        Y = X.copy()
        if sigma_pos > 0:
            Y[..., :3, 3] += rng.normal(0, sigma_pos / np.sqrt(3), size=(n, p, 3))
        if sigma_orient > 0:
            dR = rotvec_to_matrix(rng.normal(0, sigma_orient / np.sqrt(3), size=(n, p, 3)))
            Y[..., :3, :3] = Y[..., :3, :3] @ dR
        if outlier_rate > 0:
            out = rng.random((n, p)) < outlier_rate
            Y[out, :3, 3] += rng.uniform(-0.5, 0.5, size=(out.sum(), 3))
        if not 0 < visibility <= 1:
            raise ValueError(f"visibility must be in (0, 1], got {visibility}")
        seen = rng.random((n, p)) < visibility
        seen[:, list(occluded)] = False
        Y[~seen] = np.nan
        return Y, X

    def joints_between(self, i: int, j: int) -> frozenset:
        """Action signals on the kinematic path between parts i and j (ground truth)."""
        def chain(p):
            out = []
            while p is not None:
                out.append(p)
                p = self.parts[p].parent
            return out
        ci, cj = chain(i), chain(j)
        common = set(ci) & set(cj)
        path = [p for p in ci if p not in common] + [p for p in cj if p not in common]
        return frozenset(self.parts[p].action for p in path
                         if self.parts[p].joint != "rigid")

    def engineered_models(self, edges=None) -> list:
        """Exact ("hand-calibrated") local models of the *current* arm, frozen against later
        failures: by default one per parent-child edge. ``edges``: list of (i, j)."""
        import copy

        from mmlearn.models.body_schema.local import EngineeredModel

        frozen = copy.deepcopy(self)
        if edges is None:
            edges = [(part.parent, p) for p, part in enumerate(self.parts)
                     if part.parent is not None]
        out = []
        for i, j in edges:
            Q = tuple(sorted(self.joints_between(i, j)))

            def f(qQ, i=i, j=j, Q=Q):
                qQ = np.atleast_2d(qQ)
                A = np.zeros((len(qQ), frozen.n_actions))
                A[:, list(Q)] = qQ
                return frozen.local_transform(i, j, A)

            out.append(EngineeredModel(i, j, Q, self.n_actions, f))
        return out

    def local_transform(self, i: int, j: int, actions) -> np.ndarray:
        """True x_i^-1 x_j (n, 4, 4) for commanded actions (n, m)."""
        X = self.forward(np.atleast_2d(actions))
        return np.linalg.inv(X[:, i]) @ X[:, j]


def make_arm_2dof() -> SimArm:
    """2-DOF arm of Fig. 3.3: trunk x1, shoulder x2 (rigid), upper arm x3 (q1, yaw),
    lower arm x4 (q2, pitch), gripper x5 (rigid). Links 0.4 m; actions in [-pi/2, pi/2]."""
    parts = [
        ArmPart("x1_trunk", None),
        ArmPart("x2_shoulder", 0, A=trans(z=0.3)),
        ArmPart("x3_upper_arm", 1, joint="revolute", action=0, axis=(0, 0, 1),
                B=trans(x=0.4)),
        ArmPart("x4_lower_arm", 2, joint="revolute", action=1, axis=(0, 1, 0),
                B=trans(x=0.4)),
        ArmPart("x5_gripper", 3, B=rot((0, 1, 0), 0.3) @ trans(x=0.1, z=0.02)),
    ]
    return SimArm(parts, -np.pi / 2 * np.ones(2), np.pi / 2 * np.ones(2), tool_part=4)


def make_arm_4dof() -> SimArm:
    """4-DOF serial chain of Fig. 3.7: x1..x5, joints q1..q4 (z, y, y, z), links 0.25 m.
    Part 2 (x3) is the middle link a bend applies to."""
    axes = [(0, 0, 1), (0, 1, 0), (0, 1, 0), (0, 0, 1)]
    parts = [ArmPart("x1", None)]
    for a in range(4):
        parts.append(ArmPart(f"x{a + 2}", a, joint="revolute", action=a, axis=axes[a],
                             B=trans(x=0.05, z=0.25)))
    return SimArm(parts, -np.pi / 2 * np.ones(4), np.pi / 2 * np.ones(4), tool_part=4)


def make_arm_7dof() -> SimArm:
    """7-DOF arm of Fig. 3.11, 10 parts, 1.3 m long: base x1 rigid to shoulder x2; chain
    x2..x8 on revolute q1..q6 (axes alternating z, y, range +-pi/2); the gripper action q7
    (range [0, 1.5] rad) opens the two finger links x9, x10 (0.08 m, rotating in opposite
    directions about x) relative to x8. The tool part is finger x10."""
    parts = [ArmPart("x1_base", None), ArmPart("x2_shoulder", 0, A=trans(z=0.15))]
    for a in range(6):
        axis = (0, 0, 1) if a % 2 == 0 else (0, 1, 0)
        parts.append(ArmPart(f"x{a + 3}", a + 1, joint="revolute", action=a, axis=axis,
                             B=trans(x=0.04, z=0.17)))
    parts.append(ArmPart("x9_finger_left", 7, A=trans(y=0.03, z=0.1), joint="revolute",
                         action=6, axis=(1, 0, 0), B=trans(z=0.08)))
    parts.append(ArmPart("x10_finger_right", 7, A=trans(y=-0.03, z=0.1), joint="revolute",
                         action=6, axis=(-1, 0, 0), B=trans(z=0.08)))
    low = np.r_[-np.pi / 2 * np.ones(6), 0.0]
    high = np.r_[np.pi / 2 * np.ones(6), 1.5]
    return SimArm(parts, low, high, tool_part=9)
