"""The imitation-learning scene of thesis ch. 8: two tables and a cup (pick-and-place), a
whiteboard with four corner markers (zig-zag cleaning), a reach target and a box or U-shaped
obstacle; and the teacher, a human-like 7-DOF arm with other link lengths than the robot's.

World frame: the robot's (and the teacher's) base stands at the world origin on the floor
(z = 0 is the floor), the workspace is in front of it (+x), "left" seen from the robot is +y.

Observed bodies (each has a ``<body>_marker`` frame, the pose a
:class:`~mmlearn.systems.common.marker_sensor.MarkerSensor` observes; the object names of the
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

import math
from dataclasses import dataclass

import numpy as np

from mmlearn.models.imitation.scene import (TEACHER_OPENING, TEACHER_TCP_IN_X8, ImitationSceneSpec,
                                            SceneBox)
from mmlearn.sdf.builders import ArmSpec, LinkSpec, arm_model
from mmlearn.models.common.sdf_writer import Box, Cylinder, SdfModel, box_inertia, cylinder_inertia

__all__ = [
    "ImitationScene",
    "add_imitation_scene",
    "imitation_scene_sdf",
    "teacher_spec",
    "teacher_sdf",
    "add_teacher",
]


_MARKER = Box((0.04, 0.04, 0.002))
_MARK_RGBA = (0.05, 0.05, 0.05, 1.0)


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
