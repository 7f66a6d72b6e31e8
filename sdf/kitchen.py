"""A kitchen-like scene for marker-less perception of cabinet fronts (thesis ch. 5).

One model ``kitchen`` holds the room and a row of base cabinets against a wall:

* the **target module** (centred on the kitchen frame's y = 0) carries the thesis' door
  (0.395 x 0.58 m, body ``door`` on the revolute joint ``door_hinge``, hinge on a vertical
  side, pivoting about its outer face's edge like a concealed cup hinge, so that it clears
  the neighbouring front) below its drawer (0.395 x 0.125 m, body ``drawer`` on the prismatic joint
  ``drawer_slide``, with a drawer box behind the front that shows when it is pulled out);
* **planar distractors**: the wall behind, the countertop, the plinth (toe kick), a
  neighbour module on each side with *closed* fronts (bodies welded to the carcass, each
  with a frame ``<name>_face``: a door and a drawer on one side, three drawers on the other;
  :meth:`KitchenSpec.closed_fronts`), and a table standing against the wall
  beside the cabinets. The floor is :func:`mmlearn.sdf.builders.floor_sdf`.

Kitchen frame K: the carcass front face is the plane x = 0, the carcass extends to -x, the
wall is behind it, the robot stands on the +x side, z is up. Seen from the robot, "left"
is -y. Every front is a box ``front_thickness`` thick standing ``front_standoff`` in front
of the carcass, with a reveal (gap) ``front_gap`` to its neighbours, so fronts show in
depth as rectangles slightly proud of the carcass. The moving door and drawer open with
positive joint values (the door swings towards +x).

Frames ``door_face`` and ``drawer_face`` sit at the centre of each moving front's outer
face, in the :class:`mmlearn.models.perception.fronts.FrontRectangle` convention: x along the width
(= K's +y at q = 0), y along the height (K's +z), z the outward normal (K's +x).

Visual colours are distinct per front (perception does not use them; a depth camera sees
only geometry) and every visual gets Drake's default perception properties, so the
RgbdSensor's label image labels each body (``door``, ``drawer``, ``carcass``) apart.

Units: metres, kilograms, radians.
"""


import math
from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.config import param, validate_fields
from mmlearn.sdf.builders import _panel_inertia, _slab
from mmlearn.models.common.sdf_writer import Box, SdfModel

__all__ = ["KitchenSpec", "kitchen_sdf", "THESIS_DOOR", "THESIS_DRAWER"]

#: the thesis' door and drawer fronts (5.2.2): width x height, m
THESIS_DOOR = (0.395, 0.58)
THESIS_DRAWER = (0.395, 0.125)


@dataclass
class KitchenSpec:
    """Geometry of the kitchen scene (all lengths in m; load with ``yaml_load_typed``).

    Attributes:
        door_width, door_height: the moving door's front (thesis: 0.395 x 0.58).
        drawer_width, drawer_height: the moving drawer's front (thesis: 0.395 x 0.125).
        door_hinge: "left" or "right": the vertical side the door's hinge is on, seen from
            the robot (left = the kitchen's -y side).
        front_thickness: thickness of every front (a box), m.
        front_gap: reveal between neighbouring fronts and to the plinth / countertop, m.
        front_standoff: gap between a front's back face and the carcass front edge, m.
        plinth_height: height of the toe kick under the fronts, m.
        plinth_setback: how far the toe kick is set back from the carcass front, m.
        carcass_depth: depth of the base cabinets (front edge to back), m.
        countertop_thickness, countertop_overhang: countertop slab and its overhang beyond
            the fronts, m.
        wall_gap: space between the carcass back and the wall, m.
        wall_width, wall_height: size of the wall behind the cabinets, m.
        neighbours: add the neighbour modules with closed fronts left and right.
        table: add the table beside the cabinets (distractor planes: top and legs).
        table_size: length (along x), width (along y) and height of the table, m.
        table_y: y of the table's centre in K (negative: on the robot's left), m.
        drawer_depth: depth of the drawer box behind the moving drawer front, m.
        door_limit: upper joint limit of the door, rad.
        drawer_limit: upper joint limit of the drawer, m.
        pose: x, y, yaw of the kitchen frame in the world (m, m, rad).
    """

    door_width: float = param(THESIS_DOOR[0], unit="m", gt=0)
    door_height: float = param(THESIS_DOOR[1], unit="m", gt=0)
    drawer_width: float = param(THESIS_DRAWER[0], unit="m", gt=0)
    drawer_height: float = param(THESIS_DRAWER[1], unit="m", gt=0)
    door_hinge: str = param("left", choices=("left", "right"))
    front_thickness: float = param(0.019, unit="m", gt=0)
    front_gap: float = param(0.005, unit="m", gt=0)
    front_standoff: float = param(0.002, unit="m", ge=0)
    plinth_height: float = param(0.10, unit="m", gt=0)
    plinth_setback: float = param(0.05, unit="m", ge=0)
    carcass_depth: float = param(0.56, unit="m", gt=0)
    countertop_thickness: float = param(0.03, unit="m", gt=0)
    countertop_overhang: float = param(0.02, unit="m", ge=0)
    wall_gap: float = param(0.02, unit="m", ge=0)
    wall_width: float = param(6.0, unit="m", gt=0)
    wall_height: float = param(2.4, unit="m", gt=0)
    neighbours: bool = param(True)
    table: bool = param(True)
    table_size: list[float] = param([0.8, 0.8, 0.74], unit="m", length=3, gt=0, factory=True)
    table_y: float = param(-1.45, unit="m")
    drawer_depth: float = param(0.45, unit="m", gt=0)
    door_limit: float = param(math.radians(120), unit="rad", gt=0)
    drawer_limit: float = param(0.45, unit="m", gt=0)
    pose: list[float] = param([0.0, 0.0, 0.0], unit="m, m, rad", length=3, elements=True,
                              factory=True)

    def __post_init__(self):
        self.validate()

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first bad field."""
        validate_fields(self)
        if self.drawer_depth >= self.carcass_depth:
            raise ValueError(f"KitchenSpec: drawer_depth ({self.drawer_depth} m) must be less "
                             f"than carcass_depth ({self.carcass_depth} m)")

    # -- derived geometry (kitchen frame K) ----------------------------------------------
    @property
    def module_width(self) -> float:
        """Width of one cabinet module (a front plus one reveal), m."""
        return max(self.door_width, self.drawer_width) + self.front_gap

    @property
    def door_bottom(self) -> float:
        """Height of the door's lower edge, m."""
        return self.plinth_height + self.front_gap

    @property
    def drawer_bottom(self) -> float:
        return self.door_bottom + self.door_height + self.front_gap

    @property
    def carcass_height(self) -> float:
        """Height of the carcass top (the countertop rests on it), m."""
        return self.drawer_bottom + self.drawer_height + self.front_gap

    @property
    def front_back_x(self) -> float:
        """x of the fronts' back faces (closed), m."""
        return self.front_standoff

    @property
    def front_face_x(self) -> float:
        """x of the fronts' outer faces (closed), m."""
        return self.front_standoff + self.front_thickness

    def X_WK(self) -> np.ndarray:
        """Pose of the kitchen frame in the world, (4, 4)."""
        x, y, yaw = (float(v) for v in self.pose)
        c, s = math.cos(yaw), math.sin(yaw)
        T = np.eye(4)
        T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        T[:3, 3] = [x, y, 0.0]
        return T

    def face_K(self, front: str) -> np.ndarray:
        """Pose (4, 4) in K of the closed front's outer-face centre (FrontRectangle axes)."""
        T = np.eye(4)
        T[:3, :3] = np.column_stack([[0, 1, 0], [0, 0, 1], [1, 0, 0]])
        if front == "door":
            T[:3, 3] = [self.front_face_x, 0.0, self.door_bottom + self.door_height / 2]
        elif front == "drawer":
            T[:3, 3] = [self.front_face_x, 0.0, self.drawer_bottom + self.drawer_height / 2]
        else:
            raise ValueError(f"front must be 'door' or 'drawer', got {front!r}")
        return T

    def closed_fronts(self) -> list[tuple[str, float, float, float, float]]:
        """The fixed (distractor) fronts of the neighbour modules: (name, y of the centre,
        z of the lower edge, width, height), m, kitchen frame; empty without neighbours."""
        if not self.neighbours:
            return []
        Wm, H = self.module_width, self.carcass_height
        w = Wm - self.front_gap
        hl = (H - self.plinth_height - self.front_gap) / 3 - self.front_gap
        out = [(f"left_drawer{k}", -Wm, self.door_bottom + k * (hl + self.front_gap), w, hl)
               for k in range(3)]
        out += [("right_door", Wm, self.door_bottom, w, self.door_height),
                ("right_drawer", Wm, self.drawer_bottom, w, self.drawer_height)]
        return out

    def front_size(self, front: str) -> tuple[float, float]:
        """(width, height) of a moving front, m."""
        if front == "door":
            return self.door_width, self.door_height
        if front == "drawer":
            return self.drawer_width, self.drawer_height
        raise ValueError(f"front must be 'door' or 'drawer', got {front!r}")


_WOOD = (0.62, 0.50, 0.36, 1.0)
_WALL = (0.86, 0.84, 0.78, 1.0)
_TOP = (0.30, 0.30, 0.32, 1.0)
_PLINTH = (0.20, 0.20, 0.20, 1.0)
_DOOR = (0.93, 0.93, 0.90, 1.0)
_DRAWER = (0.80, 0.85, 0.95, 1.0)
_NEIGHBOUR = ((0.70, 0.80, 0.70, 1.0), (0.90, 0.80, 0.60, 1.0), (0.85, 0.70, 0.70, 1.0))
_TABLE = (0.55, 0.40, 0.28, 1.0)


def _carcass_box(link, name: str, y0: float, s: KitchenSpec) -> None:
    """The panels of one module's carcass (sides, bottom, back), centred at y = y0."""
    W, D, H, t = s.module_width, s.carcass_depth, s.carcass_height, 0.018
    P = s.plinth_height
    for args in ((f"{name}_side_l", (-D / 2, y0 - W / 2 + t / 2, (P + H) / 2), (D, t, H - P)),
                 (f"{name}_side_r", (-D / 2, y0 + W / 2 - t / 2, (P + H) / 2), (D, t, H - P)),
                 (f"{name}_bottom", (-D / 2, y0, P + t / 2), (D, W, t)),
                 (f"{name}_back", (-D + t / 2, y0, (P + H) / 2), (t, W, H - P))):
        _slab(link, *args, _WOOD)


def kitchen_sdf(spec: KitchenSpec | None = None, *, model_name: str = "kitchen") -> str:
    """SDFormat text of the kitchen scene (see the module docstring)."""
    s = spec or KitchenSpec()
    s.validate()
    x, y, yaw = s.pose
    m = SdfModel(model_name, pose=(x, y, 0, 0, 0, yaw), digits=12)
    Wm, D, H, th = s.module_width, s.carcass_depth, s.carcass_height, s.front_thickness
    n_side = 1 if s.neighbours else 0
    row_w = Wm * (1 + 2 * n_side)

    carcass = m.link("carcass")
    _panel_inertia(carcass, 40.0, (-D / 2, 0, H / 2), (D, row_w, H))
    # wall behind the row, countertop, plinth
    wall_t = 0.10
    _slab(carcass, "wall", (-D - s.wall_gap - wall_t / 2, 0, s.wall_height / 2),
          (wall_t, s.wall_width, s.wall_height), _WALL)
    top_d = D + s.front_face_x + s.countertop_overhang
    _slab(carcass, "countertop",
          (s.front_face_x + s.countertop_overhang - top_d / 2, 0,
           H + s.countertop_thickness / 2), (top_d, row_w + 0.02, s.countertop_thickness), _TOP)
    _slab(carcass, "plinth", (-s.plinth_setback - 0.01, 0, s.plinth_height / 2),
          (0.02, row_w, s.plinth_height), _PLINTH)
    # carcasses of the modules, and the rail between the target module's door and drawer
    for i in range(-n_side, n_side + 1):
        _carcass_box(carcass, f"module{i + n_side}", i * Wm, s)
    rail_z = s.drawer_bottom - s.front_gap / 2
    _slab(carcass, "rail", (-0.05, 0, rail_z), (0.10, Wm - 0.036, 0.018), _WOOD)
    # closed neighbour fronts (distractors): each its own body welded to the carcass, so the
    # label image tells them apart, with a frame <name>_face like the moving fronts'
    colours = {"left_drawer0": _NEIGHBOUR[0], "left_drawer1": _NEIGHBOUR[1],
               "left_drawer2": _NEIGHBOUR[2], "right_door": _NEIGHBOUR[0],
               "right_drawer": _NEIGHBOUR[1]}
    for name, yc, zb, w, h in s.closed_fronts():
        link = m.link(name, pose=(s.front_back_x, yc, zb))
        _panel_inertia(link, 2.0, (th / 2, 0, h / 2), (th, w, h))
        _slab(link, f"{name}_front", (th / 2, 0, h / 2), (th, w, h), colours[name])
        m.joint(f"{name}_weld", "fixed", "carcass", name)
        m.frame(f"{name}_face", attached_to=name,
                pose=(th, 0, h / 2, math.pi / 2, 0, math.pi / 2), relative_to=name)
    # table against the wall beside the row
    if s.table:
        L, Wt, Ht = s.table_size
        tx = -D - s.wall_gap + L / 2 + 0.02
        ty = s.table_y
        if abs(ty) < row_w / 2 + Wt / 2:
            raise ValueError(f"KitchenSpec.table_y = {ty} m puts the table into the cabinet "
                             f"row (|table_y| must be >= {row_w / 2 + Wt / 2:.3f} m)")
        _slab(carcass, "table_top", (tx, ty, Ht - 0.015), (L, Wt, 0.03), _TABLE)
        for k, (sx, sy) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
            _slab(carcass, f"table_leg{k}", (tx + sx * (L / 2 - 0.04), ty + sy * (Wt / 2 - 0.04),
                                             (Ht - 0.03) / 2), (0.05, 0.05, Ht - 0.03), _TABLE)
    m.joint("carcass_weld", "fixed", "world", "carcass")

    # the moving door: body frame on the hinge line (outer face, hinge edge, lower edge). The
    # pivot is on the outer face like a concealed (cup) hinge's: a door pivoting about its
    # back edge would swing its hinge edge 19 mm sin(q) into the neighbouring front (through
    # the 5 mm reveal), hiding ~1 cm of the door's hinge side from the camera.
    dw, dh = s.door_width, s.door_height
    sign = -1.0 if s.door_hinge == "left" else 1.0  # y side of the hinge
    door = m.link("door", pose=(s.front_face_x, sign * dw / 2, s.door_bottom))
    pc = (-th / 2, -sign * dw / 2, dh / 2)
    _panel_inertia(door, 3.0, pc, (th, dw, dh))
    _slab(door, "door_front", pc, (th, dw, dh), _DOOR)
    # positive q swings the free edge towards +x: axis -z for a hinge on -y, +z on +y
    m.joint("door_hinge", "revolute", "carcass", "door", axis=(0, 0, sign), lower=0.0,
            upper=s.door_limit, effort=0, velocity=5, damping=0.5)
    m.frame("door_face", attached_to="door",
            pose=(0, -sign * dw / 2, dh / 2, math.pi / 2, 0, math.pi / 2), relative_to="door")

    # the moving drawer: body frame at the front's back face, lower edge, centre
    rw, rh = s.drawer_width, s.drawer_height
    drawer = m.link("drawer", pose=(s.front_back_x, 0, s.drawer_bottom))
    _panel_inertia(drawer, 2.5, (-s.drawer_depth / 2, 0, rh / 2),
                   (s.drawer_depth, rw - 0.06, rh))
    _slab(drawer, "drawer_front", (th / 2, 0, rh / 2), (th, rw, rh), _DRAWER)
    bw, bd, bh = rw - 0.06, s.drawer_depth, max(rh - 0.03, 0.02)
    for name, c, size in (("drawer_box_bottom", (-bd / 2, 0, 0.015), (bd, bw, 0.012)),
                          ("drawer_box_l", (-bd / 2, -bw / 2, bh / 2), (bd, 0.012, bh)),
                          ("drawer_box_r", (-bd / 2, bw / 2, bh / 2), (bd, 0.012, bh)),
                          ("drawer_box_back", (-bd, 0, bh / 2), (0.012, bw, bh))):
        link_box = Box(size)
        drawer.visual(name, link_box, pose=c, color=_WOOD)
    m.joint("drawer_slide", "prismatic", "carcass", "drawer", axis=(1, 0, 0), lower=0.0,
            upper=s.drawer_limit, effort=0, velocity=2, damping=2.0)
    m.frame("drawer_face", attached_to="drawer",
            pose=(th, 0, rh / 2, math.pi / 2, 0, math.pi / 2), relative_to="drawer")
    return m.to_string()
