"""Randomised single-mechanism furniture for the door/drawer opening task (thesis 4.3, 4.4.2).

Five kinds, as in the thesis' experiment with the robot Cody: a cabinet door opening to the
left (hinge on the left edge as seen from the robot), one opening to the right, a dishwasher
door (horizontal hinge at its bottom, folding down), a drawer, and a sliding door.

Frame of the furniture (model frame F): the front face is the plane x = 0, the carcass
extends to -x, the robot stands on the +x side, z is up. Each model has a fixed body
``carcass`` and a moving body ``front`` on the joint ``mechanism`` (positive q opens); the
handle is a bar standing ``handle_standoff`` m off the front, with posts at its ends, and the
frame ``handle`` at its centre (x: out of the front, z: along the bar).

:func:`sample_mechanism` draws the geometry from a seed (door width 0.3-0.6 m, handle
offset, hinge damping and friction, drawer depth, placement of the furniture in the room).
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from mmlearn.sdf.builders import _bar_handle, _panel_inertia, _slab
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.sdf_writer import SdfModel

KINDS = ("left_door", "right_door", "dishwasher", "drawer", "sliding_door")
REVOLUTE = ("left_door", "right_door", "dishwasher")
_AXES = {"left_door": (0, 0, -1), "right_door": (0, 0, 1), "dishwasher": (0, 1, 0),
         "drawer": (1, 0, 0), "sliding_door": (0, -1, 0)}


@dataclass
class MechanismSpec:
    """Geometry and dynamics of one mechanism (m, rad, N*m*s/rad or N*s/m, N*m or N).

    Attributes:
        kind: one of ``KINDS``.
        width, height: size of the moving front, m.
        depth: carcass depth (drawer depth for a drawer), m.
        bottom: height of the front's lower edge above the floor, m.
        handle_offset: distance of the handle from the front's free edge (doors) or its
            centre height offset (drawer), m.
        handle_height: height of the handle centre above the front's lower edge, m.
        handle_standoff: distance of the bar's centre from the front surface, m.
        damping, friction: joint damping and Coulomb friction.
        spring: a closing spring's stiffness (N*m/rad or N/m; reference: closed, q = 0),
            added to a dishwasher's counterbalance spring.
        limit: upper joint limit (rad or m): the end stop, or where a jammed mechanism
            blocks (a latched one: just above 0).
        pose: x, y, yaw of the furniture in the world (m, m, rad).
    """

    kind: str = param("left_door", choices=KINDS)
    width: float = param(0.45, unit="m", gt=0)
    height: float = param(0.60, unit="m", gt=0)
    depth: float = param(0.45, unit="m", gt=0)
    bottom: float = param(0.25, unit="m")
    handle_offset: float = param(0.07, unit="m")
    handle_height: float = param(0.35, unit="m")
    handle_standoff: float = param(0.07, unit="m", gt=0)
    damping: float = param(0.5, unit="N*m*s/rad or N*s/m", ge=0)
    friction: float = param(0.3, unit="N*m or N", ge=0)
    spring: float = param(0.0, unit="N*m/rad or N/m", ge=0)
    limit: float = param(math.radians(100), unit="rad or m", gt=0)
    pose: list[float] = param([0.0, 0.0, 0.0], unit="m, m, rad", length=3, elements=True,
                              factory=True)

    def __post_init__(self):
        validate_fields(self)

    @property
    def is_revolute(self) -> bool:
        return self.kind in REVOLUTE

    # -- ground truth in the furniture frame F ---------------------------------------------
    def joint_axis_F(self) -> np.ndarray:
        """Joint axis in F (positive q opens)."""
        return np.array(_AXES[self.kind], float)

    def front_origin_F(self) -> np.ndarray:
        """Origin of the moving body (on the joint axis for revolute joints), in F."""
        g, pt = 0.004, 0.02
        x = g + pt / 2
        if self.kind == "left_door":
            return np.array([x, -self.width / 2, self.bottom])
        if self.kind == "right_door":
            return np.array([x, self.width / 2, self.bottom])
        if self.kind == "dishwasher":
            return np.array([x, 0.0, self.bottom])
        if self.kind == "sliding_door":
            return np.array([x + pt + 0.004, 0.0, self.bottom])
        return np.array([x, 0.0, self.bottom])

    def handle_in_front(self) -> tuple[np.ndarray, np.ndarray]:
        """Handle centre and bar direction in the moving body's frame."""
        pt = 0.02
        xs = pt / 2 + self.handle_standoff
        w, h = self.width, self.height
        if self.kind == "left_door":
            return np.array([xs, w - self.handle_offset, self.handle_height]), np.array([0, 0, 1.0])
        if self.kind == "right_door":
            return (np.array([xs, -(w - self.handle_offset), self.handle_height]),
                    np.array([0, 0, 1.0]))
        if self.kind == "dishwasher":
            return np.array([xs, 0.0, h - self.handle_offset]), np.array([0, 1.0, 0])
        if self.kind == "sliding_door":
            return (np.array([xs, w / 2 - self.handle_offset, self.handle_height]),
                    np.array([0, 0, 1.0]))
        return np.array([xs, 0.0, h / 2]), np.array([0, 1.0, 0])  # drawer

    def X_WF(self) -> np.ndarray:
        x, y, yaw = self.pose
        c, s = math.cos(yaw), math.sin(yaw)
        T = np.eye(4)
        T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        T[:3, 3] = [x, y, 0]
        return T

    def handle_world(self, q: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Handle centre, front normal (out of the front) and bar direction in the world
        at joint position q."""
        p, bar = self.handle_in_front()
        R = (Rotation.from_rotvec(self.joint_axis_F() * q).as_matrix() if self.is_revolute
             else np.eye(3))
        t = np.zeros(3) if self.is_revolute else self.joint_axis_F() * q
        T = self.X_WF()
        o = self.front_origin_F()
        p_F = o + R @ p + t
        n_F = R @ np.array([1.0, 0, 0])
        b_F = R @ bar
        return (T[:3, :3] @ p_F + T[:3, 3], T[:3, :3] @ n_F, T[:3, :3] @ b_F)

    def axis_world(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint axis direction and a point on it (the hinge line for revolute), world."""
        T = self.X_WF()
        return T[:3, :3] @ self.joint_axis_F(), T[:3, :3] @ self.front_origin_F() + T[:3, 3]


def sample_mechanism(kind: str, rng: np.random.Generator | int | None = None) -> MechanismSpec:
    """Draw a random mechanism of the given kind (thesis 4.4.2 variety)."""
    if kind not in KINDS:
        raise ValueError(f"mechanism kind must be one of {KINDS}, got {kind!r}")
    rng = np.random.default_rng(rng)
    u = rng.uniform
    yaw = u(-0.15, 0.15)
    pose = [u(-0.1, 0.1), u(-0.1, 0.1), yaw]
    if kind in ("left_door", "right_door"):
        return MechanismSpec(kind=kind, width=u(0.3, 0.6), height=u(0.5, 0.7),
                             depth=u(0.35, 0.5), bottom=u(0.25, 0.4),
                             handle_offset=u(0.05, 0.09), handle_height=u(0.25, 0.4),
                             damping=u(0.2, 1.5), friction=u(0.1, 0.6),
                             limit=math.radians(120), pose=pose)
    if kind == "dishwasher":
        return MechanismSpec(kind=kind, width=u(0.45, 0.6), height=u(0.5, 0.65),
                             depth=u(0.5, 0.6), bottom=u(0.1, 0.15),
                             handle_offset=u(0.05, 0.08), damping=u(0.5, 2.0),
                             friction=u(0.2, 0.8), limit=math.radians(90), pose=pose)
    if kind == "drawer":
        depth = u(0.5, 0.65)
        return MechanismSpec(kind=kind, width=u(0.35, 0.6), height=u(0.15, 0.25),
                             depth=depth, bottom=u(0.55, 0.75), damping=u(2.0, 8.0),
                             friction=u(0.5, 2.0), limit=0.9 * depth, pose=pose)
    return MechanismSpec(kind=kind, width=u(0.4, 0.6), height=u(0.5, 0.7),
                         depth=u(0.35, 0.5), bottom=u(0.25, 0.4),
                         handle_offset=u(0.05, 0.09), handle_height=u(0.25, 0.4),
                         damping=u(2.0, 8.0), friction=u(0.5, 2.0),
                         limit=0.8 * u(0.4, 0.6), pose=pose)


def mechanism_sdf(spec: MechanismSpec, *, model_name: str = "mechanism") -> str:
    """SDFormat text of the furniture with one mechanism (see the module docstring)."""
    s = spec
    W, H, D, t, pt = s.width, s.height, s.depth, 0.02, 0.02
    wood = (0.72, 0.58, 0.40, 1.0)
    front_rgba = (0.85, 0.80, 0.70, 1.0)
    x, y, yaw = s.pose
    m = SdfModel(model_name, pose=(x, y, 0, 0, 0, yaw))
    # carcass around the front opening
    cw = W + 2 * t + (0.02 if s.kind != "sliding_door" else W)
    ch = s.bottom + H + t
    carcass = m.link("carcass")
    _panel_inertia(carcass, 30.0, (-D / 2, 0, ch / 2), (D, cw, ch))
    for args in (("top", (-D / 2, 0, ch - t / 2), (D, cw, t)),
                 ("floor_plate", (-D / 2, 0, s.bottom - t / 2), (D, cw, t)),
                 ("left", (-D / 2, -cw / 2 + t / 2, ch / 2), (D, t, ch)),
                 ("right", (-D / 2, cw / 2 - t / 2, ch / 2), (D, t, ch)),
                 ("back", (-D + t / 2, 0, ch / 2), (t, cw, ch)),
                 ("plinth", (-t, 0, s.bottom / 2), (2 * t, cw, s.bottom))):
        _slab(carcass, *args, wood)
    if s.kind == "sliding_door":  # the fixed half of the front, behind the sliding panel
        _slab(carcass, "fixed_panel", (pt / 2 + 0.004, -W / 2, s.bottom + H / 2), (pt, W, H),
              front_rgba)
    hp, bar = s.handle_in_front()
    if s.kind == "left_door":
        pc = (0.0, W / 2, H / 2)
    elif s.kind == "right_door":
        pc = (0.0, -W / 2, H / 2)
    elif s.kind == "sliding_door":
        pc = (0.0, W / 2, H / 2)
    else:
        pc = (0.0, 0.0, H / 2)
    mass = 3.0 if s.kind == "drawer" else 4.0
    front = m.link("front", pose=s.front_origin_F())
    _panel_inertia(front, mass, pc, (pt, W, H))
    _slab(front, "front_panel", pc, (pt, W - 0.008, H - 0.008), front_rgba)
    if s.kind == "drawer":
        iw, idp = W - 0.03, D - 0.04
        _slab(front, "drawer_bottom", (-idp / 2, 0, 0.02), (idp, iw, 0.01), wood, False)
        _slab(front, "drawer_back", (-idp, 0, H / 2), (0.01, iw, H - 0.04), wood, False)
    # the bar (0.20 m, radius 0.01 m) at the handle centre, posts back to the front (-x)
    _bar_handle(front, "handle", hp, vertical=abs(bar[2]) > 0.5, length=0.20, r=0.01,
                standoff=s.handle_standoff)
    stiffness = s.spring
    if s.kind == "dishwasher":
        # counterbalance springs, as real dishwasher doors have: a torsion spring k q with
        # k = m g h/2, so k q >= m g h/2 sin q and the door never falls open by itself
        stiffness += mass * 9.81 * (H / 2)
    spring = {"spring_reference": 0, "spring_stiffness": stiffness} if stiffness else {}
    m.joint("mechanism", "revolute" if s.is_revolute else "prismatic", "carcass", "front",
            axis=s.joint_axis_F(), lower=0, upper=s.limit, effort=0, damping=s.damping,
            **spring)
    m.joint("carcass_weld", "fixed", "world", "carcass")
    m.frame("handle", attached_to="front", pose=hp, relative_to="front")
    return m.to_string()
