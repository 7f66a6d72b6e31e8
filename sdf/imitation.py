"""The imitation-learning scene of thesis ch. 8: two tables and a cup (pick-and-place), a
whiteboard with four corner markers (zig-zag cleaning), a reach target and a box or U-shaped
obstacle; and the teacher, a human-like 7-DOF arm with other link lengths than the robot's.

World frame: the robot's (and the teacher's) base stands at the world origin on the floor
(z = 0 is the floor), the workspace is in front of it (+x), "left" seen from the robot is +y.

Observed bodies (each has a ``<body>_marker`` frame, the pose a
:class:`~mmlearn.systems.marker_sensor.MarkerSensor` observes; the object names of the
imitation-learning data types):

============ ====================================================================================
body         marker
============ ====================================================================================
table_a      top surface, at the table's edge nearest the robot (-x side), normal +z
table_b      the same on table B
cup          free body (a cylinder standing on its base); marker on its side facing the robot
             (-x) at mid-height
board        the whiteboard panel (its front face looks at the robot, normal -x); the marker
             frame ``board_marker`` is the centre of the front face
board_c0..3  four corner markers on the front face bounding the area to clean, counter-clockwise
             seen from the robot starting at the lower left: c0 lower left (+y), c1 lower right
             (-y), c2 upper right, c3 upper left
target       a small pad on a thin post: the reach target (marker on the pad's top, normal +z)
obstacle     a box (``obstacle="box"``) or a U-shaped set of walls (``obstacle="u"``, its cavity
             opens towards +y, where reaches start); marker at the centre of the obstacle's
             top face (box) or of its bottom wall's top (U)
============ ====================================================================================

Every part except the cup is welded to the world. The cup is a free body with compliant
hydroelastic contact (the table tops are rigid hydroelastic), so it stands stably on a
table in a discrete MultibodyPlant and can be held between fingers.

:func:`add_imitation_scene` parses the scene into a (not yet finalized) MultibodyPlant;
:func:`teacher_sdf` is the teacher arm. Units: metres, kilograms, radians.
"""

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .builders import ArmSpec, LinkSpec, arm_model
from .sdf_writer import Box, Cylinder, SdfModel, box_inertia, cylinder_inertia

__all__ = [
    "ImitationSceneSpec",
    "ImitationScene",
    "SceneBox",
    "add_imitation_scene",
    "imitation_scene_sdf",
    "teacher_spec",
    "teacher_sdf",
    "add_teacher",
    "TEACHER_TCP_IN_X8",
    "TEACHER_OPENING",
    "ROBOT_TCP_IN_X8",
    "OBSTACLE_KINDS",
    "OBSERVED_BODIES",
    "stratified_table_shifts",
]

OBSTACLE_KINDS = ("none", "box", "u")
#: every observed body the scene can have (those present depend on the spec's flags)
OBSERVED_BODIES = ("cup", "table_a", "table_b", "board", "board_c0", "board_c1", "board_c2",
                   "board_c3", "obstacle", "target")
#: the robot's tool centre point in its last part x8 (``arm_spec(7)``): between the fingers,
#: 0.05 m beyond x8's tip (x8 is 0.07 m long; the fingers 0.08 m), m
ROBOT_TCP_IN_X8 = (0.0, 0.0, 0.12)
#: the teacher's tool centre point in its last part x8 (the ``hand`` body sits there), m
TEACHER_TCP_IN_X8 = (0.0, 0.0, 0.11)
#: the teacher's finger angle (q7) when its hand is fully open, rad (0 = closed: the fingers
#: stand parallel, 0.07 m apart, around the cup)
TEACHER_OPENING = 0.6

_MARKER = Box((0.04, 0.04, 0.002))
_MARK_RGBA = (0.05, 0.05, 0.05, 1.0)


@dataclass
class SceneBox:
    """A welded box of the scene (for collision-free planning in ``models``): centre (3,)
    and half extents (3,) in the world, m, rotation R (3, 3) (identity here)."""

    name: str
    centre: np.ndarray
    half_size: np.ndarray
    R: np.ndarray = field(default_factory=lambda: np.eye(3))


@dataclass
class ImitationSceneSpec:
    """Layout of the imitation scene (load with ``yaml_load_typed``; all lengths in m).

    The nominal layout is the one given by the fields; :meth:`sampled` draws a seeded
    variation of it (positions, sizes, cup placement) and :meth:`resolved` applies
    ``swap_tables`` and ``board_scale``: build the plant from ``spec.resolved()``'s numbers
    (:func:`add_imitation_scene` does).

    Attributes:
        tables: add the two tables.
        cup: add the cup (on table A, or on the table at table B's place when swapped).
        board: add the whiteboard with its corner markers.
        target: add the reach target.
        obstacle: "none", "box" or "u" (U-shaped).
        table_a, table_b: x, y of each table top's centre.
        table_size: x, y extent of a table top.
        table_height: height of the table tops above the floor.
        swap_tables: exchange the places of table A and table B (the cup still starts on
            table A, so it travels the other way; thesis Fig. 8.5).
        cup_offset: x, y of the cup's centre relative to table A's top centre.
        place_offset: x, y of the demonstrated place spot relative to table B's top centre
            (used by the teacher; the scene has no geometry there).
        cup_radius, cup_height: the cup cylinder.
        cup_mass: kg.
        cup_modulus: hydroelastic modulus of the cup, Pa.
        board_centre: x, y, z of the centre of the board's front face.
        board_size: width (along y) and height (along z) of the board panel.
        board_area: width and height of the area inside the four corner markers at scale 1.
        board_scale: scale of that area (thesis Fig. 8.8: boards of other sizes).
        target_position: x, y, z of the target pad's top centre.
        obstacle_centre: x, y, z of the box obstacle's centre, or of the U's bottom wall's
            centre.
        obstacle_size: full x, y, z extent of the box obstacle.
        u_inner_width: inner width of the U along x.
        u_depth: length of the U's side walls along +y (from the bottom wall's centre).
        u_height: height of the U's walls (z extent).
        u_thickness: wall thickness.
        seed: seed of the variation drawn by :meth:`sampled` (recorded; None = nominal).
    """

    tables: bool = True
    cup: bool = True
    board: bool = False
    target: bool = False
    obstacle: str = "none"
    table_a: list[float] = field(default_factory=lambda: [0.50, 0.32])
    table_b: list[float] = field(default_factory=lambda: [0.50, -0.32])
    table_size: list[float] = field(default_factory=lambda: [0.30, 0.30])
    table_height: float = 0.30
    swap_tables: bool = False
    cup_offset: list[float] = field(default_factory=lambda: [0.0, 0.0])
    place_offset: list[float] = field(default_factory=lambda: [0.0, 0.0])
    cup_radius: float = 0.03
    cup_height: float = 0.10
    cup_mass: float = 0.15
    cup_modulus: float = 1.0e6
    board_centre: list[float] = field(default_factory=lambda: [0.65, 0.0, 0.65])
    board_size: list[float] = field(default_factory=lambda: [0.70, 0.50])
    board_area: list[float] = field(default_factory=lambda: [0.30, 0.20])
    board_scale: float = 1.0
    target_position: list[float] = field(default_factory=lambda: [0.55, -0.30, 0.30])
    obstacle_centre: list[float] = field(default_factory=lambda: [0.50, 0.0, 0.40])
    obstacle_size: list[float] = field(default_factory=lambda: [0.24, 0.05, 0.22])
    u_inner_width: float = 0.24
    u_depth: float = 0.18
    u_height: float = 0.45
    u_thickness: float = 0.03
    seed: int | None = None

    # ------------------------------------------------------------------ checks
    def validate(self) -> "ImitationSceneSpec":
        """Raise ValueError naming the first bad field; returns self."""
        lists = {"table_a": 2, "table_b": 2, "table_size": 2, "cup_offset": 2,
                 "place_offset": 2, "board_centre": 3, "board_size": 2, "board_area": 2,
                 "target_position": 3, "obstacle_centre": 3, "obstacle_size": 3}
        for k, n in lists.items():
            v = np.asarray(getattr(self, k), float)
            if v.shape != (n,):
                raise ValueError(f"ImitationSceneSpec.{k} must have {n} entries, got "
                                 f"{getattr(self, k)!r}")
            if not np.all(np.isfinite(v)):
                raise ValueError(f"ImitationSceneSpec.{k} must be finite, got {v.tolist()}")
        for k in ("table_height", "cup_radius", "cup_height", "cup_mass", "cup_modulus",
                  "board_scale", "u_inner_width", "u_depth", "u_height", "u_thickness"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"ImitationSceneSpec.{k} must be a finite number > 0, got "
                                 f"{v!r}")
        for k in ("table_size", "board_size", "board_area", "obstacle_size"):
            if np.any(np.asarray(getattr(self, k), float) <= 0):
                raise ValueError(f"ImitationSceneSpec.{k} entries must be > 0")
        if self.obstacle not in OBSTACLE_KINDS:
            raise ValueError(f"ImitationSceneSpec.obstacle must be one of {OBSTACLE_KINDS}, "
                             f"got {self.obstacle!r}")
        half = np.asarray(self.table_size) / 2
        for k in ("cup_offset", "place_offset"):
            if np.any(np.abs(self.__dict__[k]) > half - self.cup_radius):
                raise ValueError(f"ImitationSceneSpec.{k} {self.__dict__[k]} puts the cup "
                                 "off the table top")
        area = np.asarray(self.board_area) * self.board_scale
        if np.any(area + 0.06 > np.asarray(self.board_size)):
            raise ValueError(f"ImitationSceneSpec: the area inside the corner markers "
                             f"({area.tolist()} m at board_scale {self.board_scale}) does not "
                             f"fit on the board ({list(self.board_size)} m)")
        if self.tables:
            d = np.abs(np.asarray(self.table_a) - np.asarray(self.table_b))
            if np.all(d < np.asarray(self.table_size)):
                raise ValueError("ImitationSceneSpec: table_a and table_b overlap")
        return self

    # ------------------------------------------------------------------ variation
    def sampled(self, seed: int | np.random.Generator, *, amplitude: float = 1.0,
                table_shift=None) -> "ImitationSceneSpec":
        """A seeded variation of this layout: each table moved independently by up to
        +-0.06 m in x and +-0.15 m in y (times ``amplitude``; so the relation of the hand to
        the table it does not work at varies much more than to the one it does: what lets a
        learner tell them apart), table tops and heights +-0.02 m, the cup anywhere within
        +-0.05 m of the top centre (staying on the top), the place spot +-0.005 m (a person
        puts the cup down at much the same spot of the target table), board centre +-0.03 m, target
        +-0.04 m, obstacle +-0.02 m. The same seed gives the same layout.

        ``table_shift`` (optional, 4 numbers in [-1, 1]: table A x, y, table B x, y as a
        fraction of those ranges) sets the tables' moves instead of drawing them (a teacher
        who spreads the layouts of a set of demonstrations on purpose,
        :func:`stratified_table_shifts`)."""
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        a = float(amplitude)

        def u(lo, n=None):
            return rng.uniform(-lo * a, lo * a, n)

        s = dataclasses.replace(self)
        shift = np.array([0.06, 0.15])
        draw = np.concatenate([u(1.0, 2), u(1.0, 2)])  # drawn always: the same stream
        if table_shift is not None:
            ts = np.asarray(table_shift, float)
            if ts.shape != (4,) or not np.all(np.abs(ts) <= 1.0):
                raise ValueError(f"ImitationSceneSpec.sampled: table_shift must be 4 numbers "
                                 f"in [-1, 1], got {table_shift!r}")
            draw = ts * a
        s.table_a = (np.asarray(self.table_a) + draw[:2] * shift).tolist()
        s.table_b = (np.asarray(self.table_b) + draw[2:] * shift).tolist()
        s.table_size = (np.asarray(self.table_size) + u(0.02, 2)).tolist()
        s.table_height = float(self.table_height + u(0.02))
        lim = np.asarray(s.table_size) / 2 - self.cup_radius - 0.01
        s.cup_offset = np.clip(np.asarray(self.cup_offset) + u(0.05, 2), -lim, lim).tolist()
        s.place_offset = np.clip(np.asarray(self.place_offset) + u(0.005, 2), -lim, lim).tolist()
        s.board_centre = (np.asarray(self.board_centre) + u(0.03, 3)).tolist()
        s.target_position = (np.asarray(self.target_position) + u(0.04, 3)).tolist()
        s.obstacle_centre = (np.asarray(self.obstacle_centre) + u(0.02, 3)).tolist()
        if not isinstance(seed, np.random.Generator):
            s.seed = int(seed)
        return s.validate()

    def resolved(self) -> "ImitationSceneSpec":
        """The spec with ``swap_tables`` applied to the positions (``swap_tables`` is then
        False); validates."""
        self.validate()
        s = dataclasses.replace(self)
        if self.swap_tables:
            s.table_a, s.table_b = list(self.table_b), list(self.table_a)
            s.swap_tables = False
        return s

    # ------------------------------------------------------------------ derived geometry
    def cup_start(self) -> np.ndarray:
        """Cup centre of the base (x, y, z) in the world at the start, m."""
        s = self.resolved()
        xy = np.asarray(s.table_a) + np.asarray(s.cup_offset)
        return np.array([xy[0], xy[1], s.table_height])

    def place_spot(self) -> np.ndarray:
        """Where the demonstrations put the cup (centre of its base), m."""
        s = self.resolved()
        xy = np.asarray(s.table_b) + np.asarray(s.place_offset)
        return np.array([xy[0], xy[1], s.table_height])

    def table_marker(self, which: str) -> np.ndarray:
        """World position of table ``"a"`` / ``"b"``'s marker, m."""
        s = self.resolved()
        c = np.asarray(s.table_a if which == "a" else s.table_b)
        return np.array([c[0] - s.table_size[0] / 2 + 0.03, c[1], s.table_height + 0.001])

    def board_corners(self) -> np.ndarray:
        """(4, 3) world positions of the corner markers c0..c3 (counter-clockwise seen from
        the robot, from the lower left), on the board's front face, m."""
        c = np.asarray(self.board_centre, float)
        w, h = np.asarray(self.board_area, float) * self.board_scale / 2
        return np.array([[c[0], c[1] + w, c[2] - h], [c[0], c[1] - w, c[2] - h],
                         [c[0], c[1] - w, c[2] + h], [c[0], c[1] + w, c[2] + h]])

    def obstacle_boxes(self) -> list[SceneBox]:
        """The obstacle as boxes in the world (empty for ``obstacle="none"``)."""
        c = np.asarray(self.obstacle_centre, float)
        if self.obstacle == "box":
            return [SceneBox("obstacle", c, np.asarray(self.obstacle_size, float) / 2)]
        if self.obstacle == "u":
            t, w, d, h = self.u_thickness, self.u_inner_width, self.u_depth, self.u_height
            out = [SceneBox("obstacle_bottom", c, np.array([w / 2 + t, t / 2, h / 2]))]
            for side, sx in (("left", -1), ("right", 1)):
                cc = c + np.array([sx * (w / 2 + t / 2), d / 2, 0.0])
                out.append(SceneBox(f"obstacle_{side}", cc, np.array([t / 2, d / 2, h / 2])))
            return out
        return []

    def obstacle_marker(self) -> np.ndarray | None:
        """World position of the obstacle's marker (top centre of the box / bottom wall)."""
        if self.obstacle == "none":
            return None
        top = (self.obstacle_size[2] if self.obstacle == "box" else self.u_height) / 2
        return np.asarray(self.obstacle_centre, float) + np.array([0.0, 0.0, top + 0.001])

    def present_objects(self) -> list[str]:
        """Names of the observed bodies this spec adds (see the module table)."""
        out = []
        if self.cup:
            out.append("cup")
        if self.tables:
            out += ["table_a", "table_b"]
        if self.board:
            out += ["board", "board_c0", "board_c1", "board_c2", "board_c3"]
        if self.obstacle != "none":
            out.append("obstacle")
        if self.target:
            out.append("target")
        return out


@dataclass
class ImitationScene:
    """What :func:`add_imitation_scene` added: the model instance, the resolved spec, the
    observed body names and the welded boxes (tables, board, obstacle) in the world."""

    model_instance: object
    spec: ImitationSceneSpec
    bodies: list[str]
    boxes: list[SceneBox]


def _hydro(m: SdfModel, collision, *, rigid: bool, modulus: float | None = None,
           mu: float = 0.8) -> None:
    pp = m.element(collision, "drake:proximity_properties")
    if rigid:
        m.element(pp, "drake:rigid_hydroelastic")
    else:
        m.element(pp, "drake:compliant_hydroelastic")
        m.element(pp, "drake:hydroelastic_modulus", modulus)
        m.element(pp, "drake:mesh_resolution_hint", 0.01)
        m.element(pp, "drake:hunt_crossley_dissipation", 5.0)
    m.element(pp, "drake:mu_dynamic", mu)
    m.element(pp, "drake:mu_static", mu)


def _marker(m: SdfModel, link, xyz, rpy) -> None:
    link.visual(f"{link.name}_marker_visual", _MARKER, pose=(*xyz, *rpy), color=_MARK_RGBA)
    m.frame(f"{link.name}_marker", attached_to=link.name, pose=(*xyz, *rpy),
            relative_to=link.name)


def _welded_box_link(m: SdfModel, name: str, origin, boxes, rgba, *, rigid_hydro=False,
                     collide=True):
    """A link at world position ``origin`` made of boxes [(centre, size)] (relative to the
    link), welded to the world."""
    link = m.link(name, pose=(*origin, 0, 0, 0))
    link.inertial(1.0, box_inertia(1.0, boxes[0][1]), pose=boxes[0][0])
    for k, (c, size) in enumerate(boxes):
        link.visual(f"{name}_v{k}", Box(size), pose=c, color=rgba)
        if collide:
            col = link.collision(f"{name}_c{k}", Box(size), pose=c)
            if rigid_hydro:
                _hydro(m, col, rigid=True)
    m.joint(f"{name}_weld", "fixed", "world", name)
    return link


def imitation_scene_sdf(spec: ImitationSceneSpec | None = None, *,
                        model_name: str = "imitation_scene") -> str:
    """SDFormat text of the scene (``spec.resolved()`` is what gets built)."""
    s = (spec or ImitationSceneSpec()).resolved()
    m = SdfModel(model_name)
    H = s.table_height
    if s.tables:
        for name, xy, rgba in (("table_a", s.table_a, (0.55, 0.4, 0.25, 1)),
                               ("table_b", s.table_b, (0.3, 0.45, 0.6, 1))):
            sx, sy = s.table_size
            top = 0.03
            link = _welded_box_link(
                m, name, (xy[0], xy[1], 0.0),
                [((0, 0, H - top / 2), (sx, sy, top)),
                 ((0, 0, (H - top) / 2), (0.06, 0.06, H - top))], rgba, rigid_hydro=True)
            _marker(m, link, (-sx / 2 + 0.03, 0.0, H + 0.001), (0, 0, 0))
    if s.cup:
        c = s.cup_start()
        r, h = s.cup_radius, s.cup_height
        link = m.link("cup", pose=(c[0], c[1], c[2], 0, 0, 0))
        link.inertial(s.cup_mass, cylinder_inertia(s.cup_mass, r, h), pose=(0, 0, h / 2))
        link.visual("cup_visual", Cylinder(r, h), pose=(0, 0, h / 2),
                    color=(0.85, 0.15, 0.15, 1))
        col = link.collision("cup_collision", Cylinder(r, h), pose=(0, 0, h / 2))
        _hydro(m, col, rigid=False, modulus=s.cup_modulus)
        _marker(m, link, (-r - 0.002, 0.0, h / 2), (0, -math.pi / 2, 0))
    if s.board:
        bc = np.asarray(s.board_centre, float)
        bw, bh = s.board_size
        th = 0.02
        link = _welded_box_link(
            m, "board", tuple(bc),
            [((th / 2, 0, 0), (th, bw, bh)),
             ((th + 0.02, 0, -(bc[2] - bh / 2) / 2 - bh / 2), (0.04, 0.04, bc[2] - bh / 2))],
            (0.95, 0.95, 0.95, 1))
        _marker(m, link, (-0.001, 0.0, 0.0), (0, -math.pi / 2, 0))
        for k, p in enumerate(s.board_corners()):
            name = f"board_c{k}"
            cl = m.link(name, pose=(p[0] - 0.001, p[1], p[2], 0, 0, 0))
            cl.inertial(0.01, (1e-6, 1e-6, 1e-6))
            _marker(m, cl, (0.0, 0.0, 0.0), (0, -math.pi / 2, 0))
            m.joint(f"{name}_weld", "fixed", "board", name)
    if s.target:
        p = np.asarray(s.target_position, float)
        link = _welded_box_link(
            m, "target", (p[0], p[1], p[2]),
            [((0, 0, -0.005), (0.08, 0.08, 0.01)), ((0, 0, -p[2] / 2), (0.015, 0.015, p[2]))],
            (0.2, 0.7, 0.2, 1), collide=False)
        _marker(m, link, (0.0, 0.0, 0.001), (0, 0, 0))
    if s.obstacle != "none":
        c = np.asarray(s.obstacle_centre, float)
        boxes = [(tuple(b.centre - c), tuple(2 * b.half_size)) for b in s.obstacle_boxes()]
        link = _welded_box_link(m, "obstacle", tuple(c), boxes, (0.8, 0.3, 0.1, 1))
        top = s.obstacle_marker() - c
        _marker(m, link, tuple(top), (0, 0, 0))
    return m.to_string()


def add_imitation_scene(plant, spec: ImitationSceneSpec | None = None, *,
                        model_name: str = "imitation_scene") -> ImitationScene:
    """Parse the scene into ``plant`` (not finalized). The cup's default pose is its start
    pose on table A. Returns what was added."""
    from pydrake.multibody.parsing import Parser

    s = (spec or ImitationSceneSpec()).resolved()
    parser = Parser(plant)
    (inst,) = parser.AddModelsFromString(imitation_scene_sdf(s, model_name=model_name), "sdf")
    boxes: list[SceneBox] = []
    if s.tables:
        for name, xy in (("table_a", s.table_a), ("table_b", s.table_b)):
            hs = np.array([s.table_size[0] / 2, s.table_size[1] / 2, s.table_height / 2])
            boxes.append(SceneBox(name, np.array([xy[0], xy[1], s.table_height / 2]), hs))
    if s.board:
        bc = np.asarray(s.board_centre, float)
        boxes.append(SceneBox("board", bc + np.array([0.01, 0, 0]),
                              np.array([0.01, s.board_size[0] / 2, s.board_size[1] / 2])))
    boxes += s.obstacle_boxes()
    return ImitationScene(model_instance=inst, spec=s, bodies=s.present_objects(), boxes=boxes)


def stratified_table_shifts(n: int, seed: int | np.random.Generator) -> np.ndarray:
    """(n, 4) table moves (A x, A y, B x, B y, fractions of their ranges in [-1, 1]) for a
    set of ``n`` demonstrations, spread on purpose (the thesis: generalisation depends on the
    variation the teacher shows): each of table A's coordinates is a Latin-hypercube sample
    (every one of n equal bins gets exactly one demonstration, in a random order) and table
    B takes the mirrored bin (bin n-1-i where A has bin i, its own position within the bin).
    So the tables' offset from each other, which is what tells the table the hand works at
    from the other one, spans the whole range even for 2 or 4 demonstrations."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    n = int(n)
    if n < 1:
        raise ValueError(f"stratified_table_shifts: n must be >= 1, got {n}")
    bins = [rng.permutation(n) for _ in range(2)]
    bins += [n - 1 - b for b in bins]
    cols = [(b + rng.uniform(0.0, 1.0, n)) / n for b in bins]
    return np.clip(2.0 * np.stack(cols, axis=1) - 1.0, -1.0, 1.0)


# ---------------------------------------------------------------------------- the teacher
def teacher_spec() -> ArmSpec:
    """The teacher: a human-like 7-DOF arm (torso, shoulder, 0.36 m upper arm, 0.33 m
    forearm, wrist, hand) with an angular gripper; the same joint layout as the robot's
    ``arm_spec(7)`` (q1..q6 + q7 fingers) but other link lengths (shoulder pitch joint at
    0.45 m instead of 0.25 m, reach 0.94 m from it instead of 1.05 m)."""
    skin = (0.85, 0.7, 0.6, 1.0)
    grey = (0.35, 0.35, 0.38, 1.0)
    y, z = (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    links = [
        LinkSpec("x1", 0.10, 0.12, shape="box", mass=8.0, color=grey),
        LinkSpec("x2", 0.30, 0.08, "x1_x2", joint_type="fixed", mass=10.0, color=grey),
        LinkSpec("x3", 0.05, 0.05, "q1", axis=z, mass=1.0, color=skin),
        LinkSpec("x4", 0.36, 0.045, "q2", axis=y, mass=2.0, color=skin),
        LinkSpec("x5", 0.03, 0.04, "q3", axis=z, mass=0.3, color=skin),
        LinkSpec("x6", 0.33, 0.035, "q4", axis=y, mass=1.2, color=skin),
        LinkSpec("x7", 0.05, 0.03, "q5", axis=z, mass=0.3, color=skin),
        LinkSpec("x8", 0.06, 0.03, "q6", axis=y, mass=0.4, color=skin),
        LinkSpec("x9", 0.08, 0.01, "q7", axis=(0, 1, 0), lower=0.0, upper=TEACHER_OPENING,
                 mass=0.05, shape="box", offset=(0.045, 0.0, 0.06), color=skin),
        LinkSpec("x10", 0.08, 0.01, "q7_mirror", axis=(0, -1, 0), lower=0.0,
                 upper=TEACHER_OPENING, mass=0.05, shape="box", offset=(-0.045, 0.0, 0.06),
                 color=skin),
    ]
    return ArmSpec(name="teacher", links=links, actions=["q1", "q2", "q3", "q4", "q5", "q6",
                                                         "q7"], mimic={"q7_mirror": "q7"},
                   tool="gripper")


def teacher_sdf(*, model_name: str = "teacher", base=(0.0, 0.0)) -> str:
    """SDFormat text of the teacher arm, its base welded to the floor at ``base`` (x, y in the
    world, m; a person stands where the task is handy, not where the robot is). Besides the parts
    x1..x10 (each with a marker) it has a body ``hand`` welded to x8 at the tool centre point
    (``TEACHER_TCP_IN_X8``) whose marker ``hand_marker`` is what the demonstrations track
    (like a motion-capture marker on the demonstrator's hand). The fingers x9, x10 (0.09 m
    apart, wide enough to straddle the cup) have no collision geometry, so they never hide
    the hand marker from a camera."""
    spec = teacher_spec()
    bx, by = (float(v) for v in base)
    m = arm_model(spec, model_name=model_name, pose=(bx, by, 0.0, 0.0, 0.0, 0.0),
                  finger_collision=False)  # visual fingers never hide the hand marker
    x8_z = [o for o in _chain_origins(spec)][-1]
    hand = m.link("hand", pose=(0.0, 0.0, x8_z + TEACHER_TCP_IN_X8[2]))
    hand.inertial(0.01, (1e-6, 1e-6, 1e-6))
    hand.visual("hand_visual", Box((0.015, 0.015, 0.015)), color=(0.1, 0.8, 0.1, 1))
    m.frame("hand_marker", attached_to="hand", pose=(0, 0, 0, 0, 0, 0), relative_to="hand")
    m.joint("hand_weld", "fixed", "x8", "hand")
    return m.to_string()


def _chain_origins(spec: ArmSpec) -> list[float]:
    """z of each serial-chain part's origin at q = 0."""
    z, out = 0.0, []
    for lk in spec.links:
        if lk.offset is None:
            out.append(z)
            z += lk.length
    return out


def add_teacher(plant, *, model_name: str = "teacher", base=(0.0, 0.0)):
    """Parse the teacher into ``plant`` (not finalized); returns its model instance."""
    from pydrake.multibody.parsing import Parser

    (inst,) = Parser(plant).AddModelsFromString(teacher_sdf(model_name=model_name, base=base),
                                                "sdf")
    return inst
