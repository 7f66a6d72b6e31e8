"""SDFormat builders for the articulated test objects of thesis Sec. 4.4.1 / 4.4.3.

All objects are built from boxes; every observed part ``<part>`` carries a marker frame
``<part>_marker`` (the pose a marker tracker observes; +z = marker normal). The root part is
welded to the world. Units: metres, kilograms, radians.

================== ================================ =============================================
object             parts                            joints
================== ================================ =============================================
two_drawer_cabinet cabinet, upper_drawer,           prismatic ``upper_slide``, ``lower_slide``
                   lower_drawer                     (+x, 0..0.4 m)
yardstick_open     seg1..seg4 (0.2 m segments)      revolute ``hinge12/23/34`` about z
yardstick_closed   seg1..seg4                       the same three hinges; the loop seg4 -> seg1 is
                                                    closed by a ball constraint that
                                                    :func:`add_object` adds to the plant (SDFormat
                                                    cannot express loops); parallelogram with
                                                    q = (theta, pi - theta, theta)
table              floor, table                     planar joint on the floor as the chain
                                                    prismatic ``table_x`` -> prismatic ``table_y``
                                                    -> revolute ``table_yaw`` (two light helper
                                                    links), i.e. (x, y, yaw)
car_door           car, door, window                revolute ``door_hinge`` (vertical axis);
                                                    revolute ``window_guide`` whose axis lies
                                                    1.9 m from the glass: the window slides down
                                                    a curved guide of radius 1.9 m
garage_door        frame, door                      planar chain ``door_x`` (prismatic x),
                                                    ``door_z`` (prismatic z), ``door_pitch``
                                                    (revolute y); the roll-up motion (vertical
                                                    segment, quarter circle, horizontal segment)
                                                    is set kinematically, see
                                                    :func:`garage_door_configuration`
================== ================================ =============================================
"""

from __future__ import annotations

import math

import numpy as np

from mmlearn.models.common.sdf_writer import Box, SdfModel, box_inertia

__all__ = [
    "OBJECTS",
    "object_sdf",
    "object_parts",
    "add_object",
    "WINDOW_GUIDE_RADIUS",
    "YARDSTICK_SEGMENT",
    "garage_door_configuration",
    "yardstick_closed_configuration",
]

YARDSTICK_SEGMENT = 0.2  # m
WINDOW_GUIDE_RADIUS = 1.9  # m
GARAGE_HEIGHT = 1.0  # vertical segment, m
GARAGE_RADIUS = 0.5  # quarter circle, m


_MARKER = Box((0.04, 0.04, 0.002))


def _link(m: SdfModel, name, pose, boxes, marker=None, mass=1.0, rgba=(0.7, 0.6, 0.45, 1)):
    """A link made of boxes [(centre, size)] (visuals ``<name>_v<k>``; its inertia is the
    first box's), with an optional marker (xyz, rpy) that adds the visual square and the
    ``<name>_marker`` frame."""
    link = m.link(name, pose=pose)
    link.inertial(mass, box_inertia(mass, boxes[0][1] if boxes else (0.01, 0.01, 0.01)))
    for k, (c, size) in enumerate(boxes):
        link.visual(f"{name}_v{k}", Box(size), pose=c, color=rgba)
    if marker is not None:
        xyz, rpy = marker
        link.visual(f"{name}_marker_visual", _MARKER, pose=(*xyz, *rpy),
                    color=(0.05, 0.05, 0.05, 1))
        m.frame(f"{name}_marker", attached_to=name, pose=(*xyz, *rpy), relative_to=name)


def _joint(m: SdfModel, name, jtype, parent, child, axis=(0, 0, 1), lower=-1.0, upper=1.0,
           pose=None):
    """A fixed joint, or an unactuated (effort 0) revolute / prismatic one with limits; the
    joint frame at ``pose`` in the child frame."""
    where = {"pose": pose, "relative_to": None if pose is None else child}
    if jtype == "fixed":
        m.joint(name, "fixed", parent, child, **where)
    else:
        m.joint(name, jtype, parent, child, axis=axis, lower=lower, upper=upper, effort=0,
                **where)


# --------------------------------------------------------------------------- objects
def _cabinet(m: SdfModel):
    W, D, H = 0.5, 0.45, 0.5
    _link(m, "cabinet", (0, 0, 0, 0, 0, 0), [((-D / 2, 0, H / 2), (D, W, H))],
          marker=((0.001, 0.2, H - 0.03), (0, math.pi / 2, 0)), mass=10)
    for name, z in (("upper_drawer", 0.36), ("lower_drawer", 0.14)):
        _link(m, name, (0, 0, z, 0, 0, 0),
              [((0.01, 0, 0), (0.02, W - 0.04, 0.18)),
               ((-D / 2 + 0.02, 0, -0.06), (D - 0.04, W - 0.06, 0.01))],
              marker=((0.021, 0, 0), (0, math.pi / 2, 0)), rgba=(0.85, 0.8, 0.7, 1))
        _joint(m, name.split("_")[0] + "_slide", "prismatic", "cabinet", name,
               axis=(1, 0, 0), lower=0.0, upper=0.4)
    _joint(m, "cabinet_weld", "fixed", "world", "cabinet")


def _yardstick(m: SdfModel):
    """The open and the closed yardstick share the SDFormat (see :func:`add_object`)."""
    L = YARDSTICK_SEGMENT
    for k in range(1, 5):
        _link(m, f"seg{k}", (L * (k - 1), 0, 0, 0, 0, 0), [((L / 2, 0, 0), (L, 0.02, 0.004))],
              marker=((L / 2, 0, 0.003), (0, 0, 0)), mass=0.05,
              rgba=(0.95, 0.85, 0.2, 1) if k % 2 else (0.9, 0.9, 0.9, 1))
    _joint(m, "seg1_weld", "fixed", "world", "seg1")
    for k in range(1, 4):
        _joint(m, f"hinge{k}{k + 1}", "revolute", f"seg{k}", f"seg{k + 1}",
               axis=(0, 0, 1), lower=-math.pi, upper=math.pi)


def _sliders(m: SdfModel, names) -> None:
    """Light helper links of a planar chain."""
    for h in names:
        _link(m, h, (0, 0, 0, 0, 0, 0), [((0, 0, 0), (0.001, 0.001, 0.001))], mass=0.01)


def _table(m: SdfModel):
    _link(m, "floor", (0, 0, 0, 0, 0, 0), [((0, 0, -0.01), (4, 4, 0.02))],
          marker=((0.6, -0.6, 0.001), (0, 0, 0)), mass=50, rgba=(0.6, 0.6, 0.6, 1))
    _sliders(m, ("table_slider_x", "table_slider_y"))
    _link(m, "table", (0, 0, 0, 0, 0, 0),
          [((0, 0, 0.72), (1.2, 0.8, 0.04))] + [
              ((sx * 0.55, sy * 0.35, 0.35), (0.04, 0.04, 0.7))
              for sx in (-1, 1) for sy in (-1, 1)],
          marker=((0.3, 0.2, 0.741), (0, 0, 0)), mass=15)
    _joint(m, "floor_weld", "fixed", "world", "floor")
    _joint(m, "table_x", "prismatic", "floor", "table_slider_x", (1, 0, 0), -3, 3)
    _joint(m, "table_y", "prismatic", "table_slider_x", "table_slider_y", (0, 1, 0), -3, 3)
    _joint(m, "table_yaw", "revolute", "table_slider_y", "table", (0, 0, 1), -math.pi, math.pi)


def _car(m: SdfModel):
    Rg = WINDOW_GUIDE_RADIUS
    _link(m, "car", (0, 0, 0, 0, 0, 0), [((-1.0, 0.8, 0.7), (4.0, 1.6, 1.0))],
          marker=((-1.5, -0.001, 0.9), (math.pi / 2, 0, 0)), mass=1000, rgba=(0.2, 0.3, 0.7, 1))
    # door: hinge (vertical) at the car's front edge x = 0, door panel extends to -x
    _link(m, "door", (0, -0.05, 0, 0, 0, 0), [((-0.55, 0, 0.6), (1.1, 0.05, 0.8))],
          marker=((-0.3, -0.026, 0.5), (math.pi / 2, 0, 0)), mass=20,
          rgba=(0.25, 0.35, 0.75, 1))
    # window glass above the door; its guide: revolute about x, axis 1.9 m inboard (+y) at the
    # glass height, so the glass moves down on a circle of radius 1.9 m
    _link(m, "window", (-0.55, -0.05, 1.2, 0, 0, 0), [((0, 0, 0), (0.9, 0.006, 0.4))],
          marker=((0.2, -0.004, 0.1), (math.pi / 2, 0, 0)), mass=3,
          rgba=(0.7, 0.85, 0.95, 0.6))
    _joint(m, "car_weld", "fixed", "world", "car")
    _joint(m, "door_hinge", "revolute", "car", "door", (0, 0, 1), -1.3, 0.0)
    _joint(m, "window_guide", "revolute", "door", "window", (1, 0, 0), -0.25, 0.0,
           pose=(0, Rg, 0, 0, 0, 0))


def _garage(m: SdfModel):
    _link(m, "frame", (0, 0, 0, 0, 0, 0),
          [((0, -1.2, 1.1), (0.1, 0.1, 2.2)), ((0, 1.2, 1.1), (0.1, 0.1, 2.2))],
          marker=((0.051, -1.2, 1.0), (0, math.pi / 2, 0)), mass=100, rgba=(0.5, 0.5, 0.5, 1))
    _sliders(m, ("door_slider_x", "door_slider_z"))
    _link(m, "door", (0, 0, 0, 0, 0, 0), [((0, 0, 0.5), (0.03, 2.3, 1.0))],
          marker=((0.016, 0.5, 0.3), (0, math.pi / 2, 0)), mass=30, rgba=(0.9, 0.9, 0.85, 1))
    _joint(m, "frame_weld", "fixed", "world", "frame")
    _joint(m, "door_x", "prismatic", "frame", "door_slider_x", (1, 0, 0), -3, 3)
    _joint(m, "door_z", "prismatic", "door_slider_x", "door_slider_z", (0, 0, 1), -3, 3)
    _joint(m, "door_pitch", "revolute", "door_slider_z", "door", (0, 1, 0), -math.pi, math.pi)


OBJECTS = {
    "two_drawer_cabinet": (_cabinet, ["cabinet", "upper_drawer", "lower_drawer"]),
    "yardstick_open": (_yardstick, ["seg1", "seg2", "seg3", "seg4"]),
    "yardstick_closed": (_yardstick, ["seg1", "seg2", "seg3", "seg4"]),
    "table": (_table, ["floor", "table"]),
    "car_door": (_car, ["car", "door", "window"]),
    "garage_door": (_garage, ["frame", "door"]),
}


def _check(name):
    if name not in OBJECTS:
        raise ValueError(f"unknown object {name!r}; choose from {', '.join(OBJECTS)}")


def object_sdf(name: str, *, model_name: str | None = None) -> str:
    """SDFormat text of the object ``name`` (see the module table); the model is called
    ``model_name`` (default: ``name``)."""
    _check(name)
    m = SdfModel(model_name or name)
    OBJECTS[name][0](m)
    return m.to_string()


def object_parts(name: str) -> list:
    """Observed parts of the object (each has a ``<part>_marker`` frame)."""
    _check(name)
    return list(OBJECTS[name][1])


def add_object(plant, name: str, *, model_name: str | None = None):
    """Parse object ``name`` into ``plant`` (not finalized yet) and, for
    ``yardstick_closed``, close the loop with a ball constraint between the free end of seg4
    and the start of seg1 (needs a discrete plant with the SAP solver). Returns
    (model instance, list of constraint ids)."""
    from pydrake.multibody.parsing import Parser

    text = object_sdf(name, model_name=model_name)
    parser = Parser(plant)
    parser.SetAutoRenaming(True)
    (inst,) = parser.AddModelsFromString(text, "sdf")
    cons = []
    if name == "yardstick_closed":
        seg1 = plant.GetBodyByName("seg1", inst)
        seg4 = plant.GetBodyByName("seg4", inst)
        cons.append(plant.AddBallConstraint(seg4, np.array([YARDSTICK_SEGMENT, 0.0, 0.0]),
                                            seg1, np.zeros(3)))
    return inst, cons


# --------------------------------------------------------------------------- configurations
def yardstick_closed_configuration(theta) -> np.ndarray:
    """Hinge angles (n, 3) of the closed yardstick (a rhombus) at opening angle theta (rad):
    (theta, pi - theta, theta) closes seg4's free end onto seg1's start."""
    th = np.atleast_1d(np.asarray(theta, float))
    return np.stack([th, np.pi - th, th], axis=1)


def garage_door_configuration(s) -> np.ndarray:
    """Planar-chain coordinates (n, 3) = (door_x m, door_z m, door_pitch rad) of the roll-up
    garage door at path length s (m) of its lower edge: up a vertical segment of
    GARAGE_HEIGHT, a quarter circle of radius GARAGE_RADIUS, then horizontally into the
    garage (-x); the panel stays tangent to the path."""
    s = np.atleast_1d(np.asarray(s, float))
    h, r = GARAGE_HEIGHT, GARAGE_RADIUS
    x = np.zeros_like(s)
    z = np.zeros_like(s)
    a = np.zeros_like(s)
    m1 = s <= h
    z[m1] = s[m1]
    m2 = (s > h) & (s <= h + np.pi * r / 2)
    t = (s[m2] - h) / r
    x[m2] = -(r - r * np.cos(t))
    z[m2] = h + r * np.sin(t)
    a[m2] = -t
    m3 = s > h + np.pi * r / 2
    x[m3] = -(r + (s[m3] - h - np.pi * r / 2))
    z[m3] = h + r
    a[m3] = -np.pi / 2
    return np.stack([x, z, a], axis=1)


if __name__ == "__main__":  # pragma: no cover
    for k in OBJECTS:
        print(k, len(object_sdf(k)), "chars")
