"""Programmatic SDFormat builders for the robots and furniture of mmlearn.

Everything is built from primitives (boxes, cylinders), so no external mesh or
``package://drake_models`` is needed. The static files in this folder are the
default parameterisations, regenerated with::

    python -m mmlearn.sdf.builders

Conventions
-----------
* Arms stand along +z at q = 0. Parts are named ``x1, x2, ...`` as in the thesis
  (chapter 3); the joints driven by action signals are named ``q1, q2, ...``.
* Every part carries a marker: a small flat square (visual only) on the link surface,
  with a frame ``<part>_marker`` whose +z axis is the square's outward normal. That
  frame is the pose a :class:`~mmlearn.systems.common.marker_sensor.MarkerSensor` observes.
* The 7-DOF arm has the thesis' 10 parts: base x1 welded to shoulder x2, the chain
  x2..x8 on revolute joints q1..q6, and an angular gripper whose two fingers x9, x10
  swing open on revolute joints ``q7`` and ``q7_mirror`` (commanded with the same value;
  like the fingers of the numpy arm in :mod:`mmlearn.models.body_schema.kinematic_sim`).
* Cabinet frame: the front face is the plane x = 0, the carcass extends to -x, the
  robot stands on the +x side. Door and drawer joints open with positive q.

Units: metres, kilograms, radians, newtons, seconds.
"""


import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.sdf_writer import Box, Cylinder, Link, SdfModel, box_inertia, cylinder_inertia

_MARKER_SIZE = 0.04  # edge of the square marker, m
_MARKER_THICKNESS = 0.002


@dataclass
class LinkSpec:
    """One arm part.

    Attributes:
        name: part name (x1, x2, ...).
        length: extent along the part's +z axis, m.
        radius: cylinder radius (or half-width for the base box), m.
        joint: name of the joint connecting it to the previous part (None = the root).
        joint_type: "revolute", "prismatic" or "fixed".
        axis: joint axis in the part frame.
        lower, upper: joint limits (rad or m).
        mass: kg.
        shape: "cylinder" or "box".
        offset: position of the part origin in the parent frame (default: parent's tip).
    """

    name: str
    length: float
    radius: float
    joint: str | None = None
    joint_type: str = "revolute"
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    lower: float = -2.6
    upper: float = 2.6
    mass: float = 1.0
    shape: str = "cylinder"
    offset: tuple[float, float, float] | None = None
    color: tuple[float, float, float, float] = (0.9, 0.55, 0.15, 1.0)


@dataclass
class ArmSpec:
    """A serial arm: parts in parent-before-child order plus the action signals."""

    name: str
    links: list[LinkSpec]
    actions: list[str] = field(default_factory=list)
    # joints commanded with the value of another action (e.g. the mirrored finger)
    mimic: dict[str, str] = field(default_factory=dict)
    # the tool at the tip: "gripper" (fingers among the links), "hook" (added by arm_model)
    # or "none"
    tool: str = "none"

    @property
    def parts(self) -> list[str]:
        return [lk.name for lk in self.links]

    @property
    def length(self) -> float:
        """Height of the arm at q = 0 (fingers counted once), m."""
        total = 0.0
        seen_tip = False
        for lk in self.links:
            if lk.offset is not None:  # fingers sit side by side at the tip
                if not seen_tip:
                    total += lk.length
                    seen_tip = True
                continue
            total += lk.length
        return total


_Y = (0.0, 1.0, 0.0)
_Z = (0.0, 0.0, 1.0)
GRIPPER_OPENING = 1.5  # rad, each finger of the 7-DOF arm's gripper (q7 in [0, 1.5])


def arm_spec(dof: int | str, *, tool: str = "gripper") -> ArmSpec:
    """The 2-, 4- or 7-DOF arm of the thesis' experiments.

    Args:
        dof: 2, 4 or 7 (or "2dof", "4dof", "7dof").
        tool: "gripper" (7-DOF only: the angular gripper with fingers x9, x10),
            "hook" (an L-shaped hook, as on the robot Cody, instead of the gripper) or
            "none".
    """
    if isinstance(dof, str):
        dof_s = dof.lower().removesuffix("dof")
        if not dof_s.isdigit():
            raise ValueError(f"arm must be one of 2dof, 4dof, 7dof; got {dof!r}")
        dof = int(dof_s)
    if tool not in ("gripper", "hook", "none"):
        raise ValueError(f"tool must be 'gripper', 'hook' or 'none'; got {tool!r}")
    grey = (0.35, 0.35, 0.38, 1.0)
    if dof == 2:
        links = [
            LinkSpec("x1", 0.10, 0.08, shape="box", mass=5.0, color=grey),
            LinkSpec("x2", 0.50, 0.035, "q1", axis=_Y, mass=1.5),
            LinkSpec("x3", 0.50, 0.03, "q2", axis=_Y, mass=1.0),
        ]
        actions = ["q1", "q2"]
    elif dof == 4:
        links = [
            LinkSpec("x1", 0.10, 0.08, shape="box", mass=5.0, color=grey),
            LinkSpec("x2", 0.10, 0.05, "q1", axis=_Z, mass=1.0),
            LinkSpec("x3", 0.35, 0.035, "q2", axis=_Y, mass=1.5),
            LinkSpec("x4", 0.35, 0.03, "q3", axis=_Y, mass=1.0),
            LinkSpec("x5", 0.20, 0.025, "q4", axis=_Y, mass=0.5),
        ]
        actions = ["q1", "q2", "q3", "q4"]
    elif dof == 7:
        links = [
            LinkSpec("x1", 0.10, 0.10, shape="box", mass=6.0, color=grey),
            LinkSpec("x2", 0.10, 0.06, "x1_x2", joint_type="fixed", mass=2.0),
            LinkSpec("x3", 0.05, 0.055, "q1", axis=_Z, mass=1.0),
            LinkSpec("x4", 0.40, 0.045, "q2", axis=_Y, mass=2.0),
            LinkSpec("x5", 0.05, 0.045, "q3", axis=_Z, mass=0.6),
            LinkSpec("x6", 0.35, 0.04, "q4", axis=_Y, mass=1.5),
            LinkSpec("x7", 0.10, 0.035, "q5", axis=_Z, mass=0.5),
            # with the gripper's 0.08 m fingers the arm is 1.30 m long (the thesis' arm)
            LinkSpec("x8", 0.07 if tool == "gripper" else 0.10, 0.035, "q6", axis=_Y,
                     mass=0.5),
        ]
        actions = ["q1", "q2", "q3", "q4", "q5", "q6"]
    else:
        raise ValueError(f"arm must have 2, 4 or 7 DOF; got {dof}")
    mimic: dict[str, str] = {}
    tip = links[-1]
    if tool == "gripper":
        if dof != 7:
            raise ValueError("the gripper is modelled on the 7-DOF arm only")
        # an angular gripper: the fingers swing open about y, in opposite directions
        links += [
            LinkSpec("x9", 0.08, 0.012, "q7", axis=(0, 1, 0), lower=0.0,
                     upper=GRIPPER_OPENING, mass=0.1, shape="box",
                     offset=(0.015, 0.0, tip.length)),
            LinkSpec("x10", 0.08, 0.012, "q7_mirror", axis=(0, -1, 0), lower=0.0,
                     upper=GRIPPER_OPENING, mass=0.1, shape="box",
                     offset=(-0.015, 0.0, tip.length)),
        ]
        actions.append("q7")
        mimic["q7_mirror"] = "q7"
    name = f"arm_{dof}dof" + ("" if tool == "gripper" or tool == "none" else f"_{tool}")
    return ArmSpec(name=name, links=links, actions=actions, mimic=mimic, tool=tool)


def _moments(mass: float, shape: str, length: float, radius: float) -> tuple:
    """Principal moments of a solid cylinder / square box (half-width ``radius``) along z."""
    if shape == "cylinder":
        return cylinder_inertia(mass, radius, length)
    w = 2 * radius
    return box_inertia(mass, (w, w, length))


def _geometry(shape: str, length: float, radius: float):
    if shape == "cylinder":
        return Cylinder(radius, length)
    w = 2 * radius
    return Box((w, w, length))


def _marker(m: SdfModel, link: Link, pose_xyz, pose_rpy) -> None:
    """Marker square on ``link`` (two visuals) and its frame ``<link>_marker``.

    The square lies in the frame's xy plane; its +z normal points out of the surface.
    """
    part = link.name
    pose = (*pose_xyz, *pose_rpy)
    link.visual(f"{part}_marker_visual", Box((_MARKER_SIZE, _MARKER_SIZE, _MARKER_THICKNESS)),
                pose=pose, color=(0.05, 0.05, 0.05, 1.0))
    link.visual(f"{part}_marker_dot",
                Box((_MARKER_SIZE / 2, _MARKER_SIZE / 2, _MARKER_THICKNESS * 1.5)),
                pose=pose, color=(1.0, 1.0, 1.0, 1.0))
    m.frame(f"{part}_marker", attached_to=part, pose=pose, relative_to=part)


def _arm_link(m: SdfModel, lk: LinkSpec, origin, *, marker: bool = True) -> Link:
    """One arm part: inertia, visual, marker (on the +x side at mid-length, normal +x) and
    collision of its primitive, which spans z = 0..length of the link frame."""
    geom = _geometry(lk.shape, lk.length, lk.radius)
    centre = (0.0, 0.0, lk.length / 2)
    link = m.link(lk.name, pose=origin)
    link.inertial(lk.mass, _moments(lk.mass, lk.shape, lk.length, lk.radius), pose=centre)
    link.visual(f"{lk.name}_visual", geom, pose=centre, color=lk.color)
    if marker:
        mx = lk.radius + _MARKER_THICKNESS / 2 + 0.001
        _marker(m, link, (mx, 0.0, lk.length / 2), (0.0, math.pi / 2, 0.0))
    link.collision(f"{lk.name}_collision", geom, pose=centre)
    return link


def _joint(m: SdfModel, name: str, jtype: str, parent: str, child: str, axis=None,
           lower=None, upper=None, effort=200.0, velocity=3.0, damping=0.0) -> None:
    """A fixed joint, or a revolute / prismatic one with limits and damping."""
    if jtype == "fixed":
        m.joint(name, "fixed", parent, child)
    else:
        m.joint(name, jtype, parent, child, axis=axis, lower=lower, upper=upper,
                effort=effort, velocity=velocity, damping=damping)


def _hook(m: SdfModel, parent: str, z0: float) -> None:
    """L-shaped hook welded at height ``z0`` on ``parent``: a rod along +z, then a
    finger along +x."""
    rod, finger, r = 0.14, 0.07, 0.012
    link = m.link("hook", pose=(0.0, 0.0, z0))
    link.inertial(0.3, _moments(0.3, "box", rod, r), pose=(0.0, 0.0, rod / 2))
    parts = [("hook_rod", (0.0, 0.0, rod / 2), Box((2 * r, 2 * r, rod))),
             ("hook_finger", (finger / 2 - r, 0.0, rod - r), Box((finger, 2 * r, 2 * r)))]
    for name, centre, geom in parts:
        link.visual(f"{name}_visual", geom, pose=centre, color=(0.2, 0.2, 0.25, 1))
    _marker(m, link, (-(r + _MARKER_THICKNESS / 2 + 0.001), 0.0, rod / 2),
            (0.0, -math.pi / 2, 0.0))
    for name, centre, geom in parts:
        link.collision(f"{name}_collision", geom, pose=centre)
    _joint(m, "hook_mount", "fixed", parent, "hook")


def _small_inertial(link: Link, mass: float, moment: float) -> None:
    link.inertial(mass, (moment, moment, moment))


#: The link a ``failure_joints`` arm can bend (thesis Table 3.2: "the middle link").
BEND_LINK = {2: "x2", 4: "x3", 7: "x4"}


def arm_sdf(dof: int | str = 7, *, tool: str = "gripper", mobile_base: bool = False,
            model_name: str | None = None, pose=None, failure_joints: bool = False) -> str:
    """SDFormat text of an arm: :func:`arm_model` of ``arm_spec(dof, tool=tool)`` (see there
    for the arguments)."""
    return arm_model(arm_spec(dof, tool=tool), mobile_base=mobile_base, model_name=model_name,
                     pose=pose, failure_joints=failure_joints).to_string()


def arm_model(spec: ArmSpec, *, mobile_base: bool = False, model_name: str | None = None,
              pose=None, failure_joints: bool = False,
              finger_collision: bool = True) -> SdfModel:
    """The SDFormat model of the arm ``spec`` (optionally on a planar mobile base); its
    ``to_string()`` is the SDFormat text, and callers may add bodies first.

    ``finger_collision=False`` leaves the fingers (links with an ``offset``) without collision
    geometry (visual only). The mobile base adds bodies ``base_x_carriage``, ``base_y_carriage``, ``mobile_base`` on joints
    ``base_x`` (prismatic x), ``base_y`` (prismatic y) and ``base_yaw`` (revolute z),
    all actuated, and welds the arm's x1 on top of it (0.30 m above the floor).
    ``pose`` (x y z roll pitch yaw, m and rad) places the model frame in the world.

    ``failure_joints`` (default False: the arm is unchanged) adds hidden, unactuated joints
    for failures the learner is not told about (see :mod:`mmlearn.systems.body_schema.arm_failures`,
    which locks them): the link ``BEND_LINK[dof]`` is split at half its length into the
    part (lower half, carrying the marker at its middle) and a body ``<part>_outer`` on the
    revolute joint ``<part>_bend`` (axis x: a bend out of the arm's pitch plane); and a
    tool part ``x<n+1>`` (a 0.12 m rod with a marker) hangs from the tip of the serial
    chain on the prismatic joint ``tool_length`` (along z, through the massless-ish body
    ``tool_mount``) and the revolute joint ``tool_angle`` (about y).
    """
    bend_link = None
    if failure_joints:
        bend_link = BEND_LINK[int(spec.name.split("_")[1].removesuffix("dof"))]
    m = SdfModel(model_name or (spec.name + ("_mobile" if mobile_base else "")), pose=pose)
    z = 0.0
    base_height = 0.30
    if mobile_base:
        z = base_height
        for carriage in ("base_x_carriage", "base_y_carriage"):
            _small_inertial(m.link(carriage), 1.0, 0.01)
        body = (0.55, 0.45, base_height - 0.05)
        base = m.link("mobile_base")
        base.inertial(40.0, (1.5, 1.8, 2.0), pose=(0.0, 0.0, 0.15))
        centre = (0.0, 0.0, 0.05 + body[2] / 2)
        base.visual("mobile_base_visual", Box(body), pose=centre, color=(0.25, 0.3, 0.45, 1))
        base.collision("mobile_base_collision", Box(body), pose=centre)
        _joint(m, "base_x", "prismatic", "world", "base_x_carriage", (1, 0, 0),
               -20, 20, effort=2000, velocity=1.0, damping=50)
        _joint(m, "base_y", "prismatic", "base_x_carriage", "base_y_carriage", (0, 1, 0),
               -20, 20, effort=2000, velocity=1.0, damping=50)
        _joint(m, "base_yaw", "revolute", "base_y_carriage", "mobile_base", (0, 0, 1),
               -2 * math.pi, 2 * math.pi, effort=1000, velocity=1.5, damping=20)
    chain_tip, chain_tip_z = None, z  # last part of the serial chain, and its origin
    for lk in spec.links:
        if lk.offset is not None:  # a finger: offset from the chain tip's origin
            parent = chain_tip.name
            origin = (lk.offset[0], lk.offset[1], chain_tip_z + lk.offset[2])
        else:
            parent = chain_tip.name if chain_tip is not None else None
            origin = (0.0, 0.0, z)
            chain_tip, chain_tip_z = lk, z
            z += lk.length
        if lk.name == bend_link:
            half = lk.length / 2
            _arm_link(m, dataclasses.replace(lk, length=half), origin)
            outer = dataclasses.replace(lk, name=f"{lk.name}_outer", length=half,
                                        mass=lk.mass / 2)
            _arm_link(m, outer, (origin[0], origin[1], origin[2] + half), marker=False)
            _joint(m, f"{lk.name}_bend", "revolute", lk.name, outer.name, (1, 0, 0),
                   -math.pi, math.pi, effort=0.0)
            chain_tip = outer
            chain_tip_z = origin[2] + half
        else:
            link = _arm_link(m, lk, origin)
            if lk.offset is not None and not finger_collision:
                for c in link.element.findall("collision"):
                    link.element.remove(c)
        if parent is None:
            _joint(m, "x1_mount", "fixed", "mobile_base" if mobile_base else "world", lk.name)
        else:
            _joint(m, lk.joint, lk.joint_type, parent, lk.name, lk.axis, lk.lower, lk.upper,
                   damping=0.5)
    if failure_joints:
        tip = chain_tip.name
        tname = f"x{len(spec.links) + 1}"
        tip_z = chain_tip_z + chain_tip.length
        _small_inertial(m.link("tool_mount", pose=(0.0, 0.0, tip_z)), 0.01, 1e-5)
        tool_lk = LinkSpec(tname, 0.12, 0.012, mass=0.1, color=(0.2, 0.6, 0.3, 1.0))
        _arm_link(m, tool_lk, (0.0, 0.0, tip_z))
        _joint(m, "tool_length", "prismatic", tip, "tool_mount", (0, 0, 1), -0.5, 0.5,
               effort=0.0)
        _joint(m, "tool_angle", "revolute", "tool_mount", tname, (0, 1, 0), -math.pi, math.pi,
               effort=0.0)
    if spec.tool == "hook":
        _hook(m, spec.links[-1].name, z)
    return m


@dataclass
class CabinetSpec:
    """Geometry of the cabinet: a drawer on top of two doors (left- and right-hinged).

    All lengths in m; damping in N*m*s/rad (doors) and N*s/m (drawer); joint friction is
    not an SDFormat feature Drake reads: it is applied by the scene diagram from
    ``door_friction`` (N*m) and ``drawer_friction`` (N).
    """

    width: float = param(0.80, unit="m", gt=0)
    height: float = param(0.90, unit="m", gt=0)
    depth: float = param(0.45, unit="m", gt=0)
    drawer_height: float = param(0.20, unit="m", gt=0)
    wall: float = param(0.02, unit="m", gt=0)
    door_damping: float = param(0.8, unit="N*m*s/rad", ge=0)
    drawer_damping: float = param(4.0, unit="N*s/m", ge=0)
    door_friction: float = param(0.3, unit="N*m", ge=0)
    drawer_friction: float = param(1.0, unit="N", ge=0)
    door_limit: float = param(math.radians(110), unit="rad")
    drawer_limit: float = param(0.38, unit="m")
    handle_offset: float = param(0.06, unit="m")  # handle distance from the door's free edge

    def __post_init__(self):
        validate_fields(self)
        if self.drawer_height >= self.height - 0.2:
            raise ValueError(f"CabinetSpec: drawer_height ({self.drawer_height} m) leaves no room "
                             f"for the doors: it must be < height - 0.2 m = "
                             f"{self.height - 0.2:g} m")



def _bar_handle(link: Link, name: str, bar_centre, *, vertical: bool, length: float, r: float,
                standoff: float) -> None:
    """A bar handle (square section 2r, ``length`` along z if ``vertical`` else y) centred
    at ``bar_centre`` and two posts (``standoff`` long, along -x) back to the front
    surface: visuals ``<name>_bar``, ``<name>_post_a/b`` and their ``..._collision``."""
    cx, cy, cz = bar_centre
    grey = (0.75, 0.75, 0.78, 1)
    bar = Box((2 * r, 2 * r, length) if vertical else (2 * r, length, 2 * r))
    link.visual(f"{name}_bar", bar, pose=(cx, cy, cz), color=grey)
    link.collision(f"{name}_bar_collision", bar, pose=(cx, cy, cz))
    post = Box((standoff, 2 * r, 2 * r))
    for s, sign in (("a", -1), ("b", 1)):
        d = sign * (length / 2 - r)
        p = (cx - standoff / 2, cy, cz + d) if vertical else (cx - standoff / 2, cy + d, cz)
        link.visual(f"{name}_post_{s}", post, pose=p, color=grey)
        link.collision(f"{name}_post_{s}_collision", post, pose=p)


def _handle(link: Link, name: str, centre, vertical: bool, length: float = 0.12) -> None:
    """A bar handle standing 0.04 m off the front surface point ``centre`` (+x)."""
    cx, cy, cz = centre
    _bar_handle(link, name, (cx + 0.045, cy, cz), vertical=vertical, length=length, r=0.008,
                standoff=0.04)


def _slab(link: Link, name: str, centre, size, rgba, collision=True) -> None:
    """A box visual ``name`` (and collision ``<name>_collision``) centred at ``centre``."""
    link.visual(name, Box(size), pose=centre, color=rgba)
    if collision:
        link.collision(f"{name}_collision", Box(size), pose=centre)


def _panel_inertia(link: Link, mass: float, centre, size) -> None:
    """Inertia of a solid box of ``size`` centred at ``centre``."""
    link.inertial(mass, box_inertia(mass, size), pose=centre)


def cabinet_sdf(spec: CabinetSpec | None = None, *, model_name: str = "cabinet",
                pose=None) -> str:
    """SDFormat text of the cabinet (body ``carcass``; ``left_door`` on ``left_hinge``,
    ``right_door`` on ``right_hinge``, ``drawer`` on ``drawer_slide``; handles are part
    of the moving bodies and their centres are frames ``<body>_handle``). ``pose`` (x y z
    roll pitch yaw) places the cabinet in the world."""
    s = spec or CabinetSpec()
    W, H, D, t = s.width, s.height, s.depth, s.wall
    wood = (0.72, 0.58, 0.40, 1.0)
    front = (0.85, 0.80, 0.70, 1.0)
    door_h = H - s.drawer_height
    m = SdfModel(model_name, pose=pose)
    carcass = m.link("carcass")
    _panel_inertia(carcass, 30.0, (-D / 2, 0, H / 2), (D, W, H))
    for args in (("top", (-D / 2, 0, H - t / 2), (D, W, t)),
                 ("bottom", (-D / 2, 0, t / 2), (D, W, t)),
                 ("left", (-D / 2, -W / 2 + t / 2, H / 2), (D, t, H)),
                 ("right", (-D / 2, W / 2 - t / 2, H / 2), (D, t, H)),
                 ("back", (-D + t / 2, 0, H / 2), (t, W, H)),
                 ("shelf", (-D / 2, 0, door_h), (D, W, t))):
        _slab(carcass, *args, wood)
    m.joint("carcass_weld", "fixed", "world", "carcass")
    gap, pt = 0.004, 0.018  # door gap to the carcass front, panel thickness
    dw = W / 2 - gap  # width of one door
    dz = door_h - 2 * gap
    x_hinge = gap + pt / 2
    for side, sign in (("left", -1), ("right", 1)):
        body = f"{side}_door"
        # door frame at the hinge: the panel extends along -sign*y from it
        pc = (0.0, -sign * dw / 2, dz / 2)
        hy = -sign * (dw - s.handle_offset)
        door = m.link(body, pose=(x_hinge, sign * (W / 2), gap))
        _panel_inertia(door, 3.0, pc, (pt, dw, dz))
        _slab(door, body + "_panel", pc, (pt, dw, dz), front)
        _handle(door, body + "_handle", (pt / 2, hy, dz * 0.6), vertical=True)
        axis = (0, 0, -1) if side == "left" else (0, 0, 1)
        _joint(m, f"{side}_hinge", "revolute", "carcass", body, axis, 0.0, s.door_limit,
               effort=0, velocity=5, damping=s.door_damping)
        m.frame(f"{body}_handle", attached_to=body, pose=(pt / 2 + 0.045, hy, dz * 0.6),
                relative_to=body)
    # drawer: front panel plus a box below/behind it
    dh = s.drawer_height - 2 * gap
    fw = W - 2 * gap
    inner_w, inner_d = W - 2 * t - 0.01, D - 2 * t - 0.02
    drawer = m.link("drawer", pose=(x_hinge, 0, door_h + gap))
    _panel_inertia(drawer, 2.5, (-inner_d / 2, 0, dh / 2), (inner_d, inner_w, dh))
    _slab(drawer, "drawer_front", (0, 0, dh / 2), (pt, fw, dh), front)
    _slab(drawer, "drawer_bottom", (-inner_d / 2, 0, 0.02), (inner_d, inner_w, 0.01), wood,
          False)
    _slab(drawer, "drawer_side_l", (-inner_d / 2, -inner_w / 2, dh / 2 - 0.02),
          (inner_d, 0.01, dh - 0.06), wood, False)
    _slab(drawer, "drawer_side_r", (-inner_d / 2, inner_w / 2, dh / 2 - 0.02),
          (inner_d, 0.01, dh - 0.06), wood, False)
    _slab(drawer, "drawer_back", (-inner_d, 0, dh / 2 - 0.02), (0.01, inner_w, dh - 0.06),
          wood, False)
    _handle(drawer, "drawer_handle", (pt / 2, 0, dh / 2), vertical=False, length=0.16)
    _joint(m, "drawer_slide", "prismatic", "carcass", "drawer", (1, 0, 0), 0.0,
           s.drawer_limit, effort=0, velocity=2, damping=s.drawer_damping)
    m.frame("drawer_handle", attached_to="drawer", pose=(pt / 2 + 0.045, 0, dh / 2),
            relative_to="drawer")
    return m.to_string()


def floor_sdf(size: float = 8.0) -> str:
    """A flat floor (box top at z = 0), welded to the world."""
    m = SdfModel("floor", static=True)
    floor = m.link("floor", pose=(0, 0, -0.05))
    floor.visual("floor_visual", Box((size, size, 0.1)), color=(0.55, 0.55, 0.55, 1))
    floor.collision("floor_collision", Box((size, size, 0.1)))
    return m.to_string()


#: Static files shipped in this folder: file name -> builder call.
DEFAULT_MODELS = {
    "arm_2dof.sdf": lambda: arm_sdf(2, tool="none"),
    "arm_4dof.sdf": lambda: arm_sdf(4, tool="none"),
    "arm_7dof.sdf": lambda: arm_sdf(7, tool="gripper"),
    "arm_7dof_hook.sdf": lambda: arm_sdf(7, tool="hook"),
    "mobile_arm_7dof_hook.sdf": lambda: arm_sdf(7, tool="hook", mobile_base=True),
    "cabinet.sdf": lambda: cabinet_sdf(),
    "floor.sdf": lambda: floor_sdf(),
}


def write_default_models(folder: str | Path | None = None) -> list[Path]:
    """(Re)write the static SDF files, each atomically (a reader never sees half a model);
    returns their paths."""
    from mmlearn.models.common.fileio import atomic_write_text

    out = Path(folder) if folder else Path(__file__).resolve().parent
    paths = []
    for fname, build in DEFAULT_MODELS.items():
        p = out / fname
        atomic_write_text(p, build())
        paths.append(p)
    return paths


if __name__ == "__main__":
    for p in write_default_models():
        print(p)
