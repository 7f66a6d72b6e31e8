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
  frame is the pose a :class:`~mmlearn.systems.marker_sensor.MarkerSensor` observes.
* The 7-DOF arm has the thesis' 10 parts: base x1 welded to shoulder x2, the chain
  x2..x8 on revolute joints q1..q6, and an angular gripper whose two fingers x9, x10
  swing open on revolute joints ``q7`` and ``q7_mirror`` (commanded with the same value;
  like the fingers of the numpy arm in :mod:`mmlearn.models.kinematic_sim`).
* Cabinet frame: the front face is the plane x = 0, the carcass extends to -x, the
  robot stands on the +x side. Door and drawer joints open with positive q.

Units: metres, kilograms, radians, newtons, seconds.
"""


import math
from dataclasses import dataclass, field
from pathlib import Path

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
    return ArmSpec(name=name, links=links, actions=actions, mimic=mimic)


def _fmt(v) -> str:
    return " ".join(f"{float(x):.6g}" for x in v)


def _inertia_xml(mass: float, shape: str, length: float, radius: float) -> str:
    """Inertia of a solid cylinder / box along z, centred at half its length."""
    if shape == "cylinder":
        ixx = mass * (3 * radius**2 + length**2) / 12.0
        izz = 0.5 * mass * radius**2
    else:
        w = 2 * radius
        ixx = mass * (w**2 + length**2) / 12.0
        izz = mass * (2 * w**2) / 12.0
    return (
        f"<inertial><pose>0 0 {length / 2:.6g} 0 0 0</pose><mass>{mass:.6g}</mass>"
        f"<inertia><ixx>{ixx:.6g}</ixx><iyy>{ixx:.6g}</iyy><izz>{izz:.6g}</izz>"
        "<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>"
    )


def _geometry(shape: str, length: float, radius: float) -> str:
    if shape == "cylinder":
        return (f"<geometry><cylinder><radius>{radius:.6g}</radius>"
                f"<length>{length:.6g}</length></cylinder></geometry>")
    w = 2 * radius
    return f"<geometry><box><size>{w:.6g} {w:.6g} {length:.6g}</size></box></geometry>"


def _box(size) -> str:
    return f"<geometry><box><size>{_fmt(size)}</size></box></geometry>"


def _material(rgba) -> str:
    return f"<material><diffuse>{_fmt(rgba)}</diffuse></material>"


def _marker_xml(part: str, pose_xyz, pose_rpy) -> tuple[str, str]:
    """Visual of a marker square on ``part`` and its frame (returned separately).

    The square lies in the frame's xy plane; its +z normal points out of the surface.
    """
    pose = f"{_fmt(pose_xyz)} {_fmt(pose_rpy)}"
    visual = (
        f"<visual name='{part}_marker_visual'><pose>{pose}</pose>"
        f"{_box((_MARKER_SIZE, _MARKER_SIZE, _MARKER_THICKNESS))}"
        f"{_material((0.05, 0.05, 0.05, 1.0))}</visual>"
        f"<visual name='{part}_marker_dot'><pose>{pose}</pose>"
        f"{_box((_MARKER_SIZE / 2, _MARKER_SIZE / 2, _MARKER_THICKNESS * 1.5))}"
        f"{_material((1.0, 1.0, 1.0, 1.0))}</visual>"
    )
    frame = (f"<frame name='{part}_marker' attached_to='{part}'>"
             f"<pose relative_to='{part}'>{pose}</pose></frame>")
    return visual, frame


def _link_xml(lk: LinkSpec, origin, collision: bool = True) -> tuple[str, str]:
    geom = _geometry(lk.shape, lk.length, lk.radius)
    centre = f"0 0 {lk.length / 2:.6g} 0 0 0"
    # marker on the +x side of the part, at mid-length, normal along +x
    mx = lk.radius + _MARKER_THICKNESS / 2 + 0.001
    marker_visual, marker_frame = _marker_xml(
        lk.name, (mx, 0.0, lk.length / 2), (0.0, math.pi / 2, 0.0))
    coll = (f"<collision name='{lk.name}_collision'><pose>{centre}</pose>{geom}</collision>"
            if collision else "")
    xml = (
        f"<link name='{lk.name}'><pose>{_fmt(origin)} 0 0 0</pose>"
        f"{_inertia_xml(lk.mass, lk.shape, lk.length, lk.radius)}"
        f"<visual name='{lk.name}_visual'><pose>{centre}</pose>{geom}"
        f"{_material(lk.color)}</visual>{marker_visual}{coll}</link>"
    )
    return xml, marker_frame


def _joint_xml(name: str, jtype: str, parent: str, child: str, axis=None,
               lower=None, upper=None, effort=200.0, velocity=3.0, damping=0.0,
               pose=None) -> str:
    pose_xml = f"<pose relative_to='{child}'>{_fmt(pose)} 0 0 0</pose>" if pose else ""
    if jtype == "fixed":
        return (f"<joint name='{name}' type='fixed'>{pose_xml}<parent>{parent}</parent>"
                f"<child>{child}</child></joint>")
    return (
        f"<joint name='{name}' type='{jtype}'>{pose_xml}<parent>{parent}</parent>"
        f"<child>{child}</child><axis><xyz>{_fmt(axis)}</xyz>"
        f"<limit><lower>{lower:.6g}</lower><upper>{upper:.6g}</upper>"
        f"<effort>{effort:.6g}</effort><velocity>{velocity:.6g}</velocity></limit>"
        f"<dynamics><damping>{damping:.6g}</damping></dynamics></axis></joint>"
    )


def _hook_xml(parent: str, z0: float) -> tuple[str, str, str]:
    """L-shaped hook welded at height ``z0`` on ``parent``: a rod along +z, then a
    finger along +x. Returns (link xml, joint xml, marker frame)."""
    rod, finger, r = 0.14, 0.07, 0.012
    coll = (
        f"<collision name='hook_rod_collision'><pose>0 0 {rod / 2:.6g} 0 0 0</pose>"
        f"{_box((2 * r, 2 * r, rod))}</collision>"
        f"<collision name='hook_finger_collision'>"
        f"<pose>{finger / 2 - r:.6g} 0 {rod - r:.6g} 0 0 0</pose>"
        f"{_box((finger, 2 * r, 2 * r))}</collision>"
    )
    vis = (
        f"<visual name='hook_rod_visual'><pose>0 0 {rod / 2:.6g} 0 0 0</pose>"
        f"{_box((2 * r, 2 * r, rod))}{_material((0.2, 0.2, 0.25, 1))}</visual>"
        f"<visual name='hook_finger_visual'>"
        f"<pose>{finger / 2 - r:.6g} 0 {rod - r:.6g} 0 0 0</pose>"
        f"{_box((finger, 2 * r, 2 * r))}{_material((0.2, 0.2, 0.25, 1))}</visual>"
    )
    marker_visual, marker_frame = _marker_xml(
        "hook", (-(r + _MARKER_THICKNESS / 2 + 0.001), 0.0, rod / 2),
        (0.0, -math.pi / 2, 0.0))
    link = (
        f"<link name='hook'><pose>0 0 {z0:.6g} 0 0 0</pose>"
        f"{_inertia_xml(0.3, 'box', rod, r)}{vis}{marker_visual}{coll}</link>"
    )
    joint = _joint_xml("hook_mount", "fixed", parent, "hook")
    return link, joint, marker_frame


def _model_pose(pose) -> str:
    if pose is None:
        return ""
    pose = [float(v) for v in pose]
    if len(pose) != 6 or not all(math.isfinite(v) for v in pose):
        raise ValueError(f"model pose must be 6 finite numbers x y z roll pitch yaw, got {pose}")
    return f"<pose>{_fmt(pose)}</pose>"


#: The link a ``failure_joints`` arm can bend (thesis Table 3.2: "the middle link").
BEND_LINK = {2: "x2", 4: "x3", 7: "x4"}


def arm_sdf(dof: int | str = 7, *, tool: str = "gripper", mobile_base: bool = False,
            model_name: str | None = None, pose=None, failure_joints: bool = False) -> str:
    """SDFormat text of an arm (optionally on a planar mobile base).

    The mobile base adds bodies ``base_x_carriage``, ``base_y_carriage``, ``mobile_base`` on joints
    ``base_x`` (prismatic x), ``base_y`` (prismatic y) and ``base_yaw`` (revolute z),
    all actuated, and welds the arm's x1 on top of it (0.30 m above the floor).
    ``pose`` (x y z roll pitch yaw, m and rad) places the model frame in the world.

    ``failure_joints`` (default False: the arm is unchanged) adds hidden, unactuated joints
    for failures the learner is not told about (see :mod:`mmlearn.systems.arm_failures`,
    which locks them): the link ``BEND_LINK[dof]`` is split at half its length into the
    part (lower half, carrying the marker at its middle) and a body ``<part>_outer`` on the
    revolute joint ``<part>_bend`` (axis x: a bend out of the arm's pitch plane); and a
    tool part ``x<n+1>`` (a 0.12 m rod with a marker) hangs from the tip of the serial
    chain on the prismatic joint ``tool_length`` (along z, through the massless-ish body
    ``tool_mount``) and the revolute joint ``tool_angle`` (about y).
    """
    spec = arm_spec(dof, tool=tool)
    bend_link = None
    if failure_joints:
        bend_link = BEND_LINK[int(spec.name.split("_")[1].removesuffix("dof"))]
    name = model_name or (spec.name + ("_mobile" if mobile_base else ""))
    links, joints, frames = [], [], []
    z = 0.0
    base_height = 0.30
    if mobile_base:
        z = base_height
        small = "<inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy>" \
                "<izz>0.01</izz><ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>"
        links.append(f"<link name='base_x_carriage'>{small}</link><link name='base_y_carriage'>{small}</link>")
        body = (0.55, 0.45, base_height - 0.05)
        links.append(
            "<link name='mobile_base'><inertial><pose>0 0 0.15 0 0 0</pose><mass>40</mass>"
            "<inertia><ixx>1.5</ixx><iyy>1.8</iyy><izz>2.0</izz><ixy>0</ixy><ixz>0</ixz>"
            "<iyz>0</iyz></inertia></inertial>"
            f"<visual name='mobile_base_visual'><pose>0 0 {0.05 + body[2] / 2:.6g} 0 0 0</pose>"
            f"{_box(body)}{_material((0.25, 0.3, 0.45, 1))}</visual>"
            f"<collision name='mobile_base_collision'><pose>0 0 {0.05 + body[2] / 2:.6g} 0 0 0"
            f"</pose>{_box(body)}</collision></link>"
        )
        joints.append(_joint_xml("base_x", "prismatic", "world", "base_x_carriage", (1, 0, 0),
                                 -20, 20, effort=2000, velocity=1.0, damping=50))
        joints.append(_joint_xml("base_y", "prismatic", "base_x_carriage", "base_y_carriage", (0, 1, 0),
                                 -20, 20, effort=2000, velocity=1.0, damping=50))
        joints.append(_joint_xml("base_yaw", "revolute", "base_y_carriage", "mobile_base", (0, 0, 1),
                                 -2 * math.pi, 2 * math.pi, effort=1000, velocity=1.5,
                                 damping=20))
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
            import dataclasses
            half = lk.length / 2
            xml, frame = _link_xml(dataclasses.replace(lk, length=half), origin)
            links.append(xml)
            frames.append(frame)
            bname = f"{lk.name}_outer"
            geom = _geometry(lk.shape, half, lk.radius)
            centre = f"0 0 {half / 2:.6g} 0 0 0"
            links.append(
                f"<link name='{bname}'><pose>{_fmt((origin[0], origin[1], origin[2] + half))}"
                f" 0 0 0</pose>{_inertia_xml(lk.mass / 2, lk.shape, half, lk.radius)}"
                f"<visual name='{bname}_visual'><pose>{centre}</pose>{geom}"
                f"{_material(lk.color)}</visual><collision name='{bname}_collision'>"
                f"<pose>{centre}</pose>{geom}</collision></link>")
            joints.append(_joint_xml(f"{lk.name}_bend", "revolute", lk.name, bname, (1, 0, 0),
                                     -math.pi, math.pi, effort=0.0))
            chain_tip = dataclasses.replace(lk, name=bname, length=half)
            chain_tip_z = origin[2] + half
        else:
            xml, frame = _link_xml(lk, origin)
            links.append(xml)
            frames.append(frame)
        if parent is None:
            joints.append(_joint_xml(
                "x1_mount", "fixed", "mobile_base" if mobile_base else "world", lk.name))
        else:
            joints.append(_joint_xml(lk.joint, lk.joint_type, parent, lk.name, lk.axis,
                                     lk.lower, lk.upper, damping=0.5))
    if failure_joints:
        tip = chain_tip.name
        tname = f"x{len(spec.links) + 1}"
        small = "<inertial><mass>0.01</mass><inertia><ixx>1e-5</ixx><iyy>1e-5</iyy>" \
                "<izz>1e-5</izz><ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>"
        links.append(f"<link name='tool_mount'><pose>0 0 {chain_tip_z + chain_tip.length:.6g}"
                     f" 0 0 0</pose>{small}</link>")
        tool_lk = LinkSpec(tname, 0.12, 0.012, mass=0.1, color=(0.2, 0.6, 0.3, 1.0))
        xml, frame = _link_xml(tool_lk, (0.0, 0.0, chain_tip_z + chain_tip.length))
        links.append(xml)
        frames.append(frame)
        joints.append(_joint_xml("tool_length", "prismatic", tip, "tool_mount", (0, 0, 1),
                                 -0.5, 0.5, effort=0.0))
        joints.append(_joint_xml("tool_angle", "revolute", "tool_mount", tname, (0, 1, 0),
                                 -math.pi, math.pi, effort=0.0))
    if tool == "hook":
        link, joint, frame = _hook_xml(spec.links[-1].name, z)
        links.append(link)
        joints.append(joint)
        frames.append(frame)
    return (
        "<?xml version='1.0'?>\n<sdf version='1.9'>"
        f"<model name='{name}'>{_model_pose(pose)}" + "".join(links) + "".join(joints)
        + "".join(frames) + "</model></sdf>\n"
    )


@dataclass
class CabinetSpec:
    """Geometry of the cabinet: a drawer on top of two doors (left- and right-hinged).

    All lengths in m; damping in N*m*s/rad (doors) and N*s/m (drawer); joint friction is
    not an SDFormat feature Drake reads: it is applied by the scene diagram from
    ``door_friction`` (N*m) and ``drawer_friction`` (N).
    """

    width: float = 0.80
    height: float = 0.90
    depth: float = 0.45
    drawer_height: float = 0.20
    wall: float = 0.02
    door_damping: float = 0.8
    drawer_damping: float = 4.0
    door_friction: float = 0.3
    drawer_friction: float = 1.0
    door_limit: float = math.radians(110)
    drawer_limit: float = 0.38
    handle_offset: float = 0.06  # handle distance from the door's free edge, m

    def __post_init__(self):
        for k in ("width", "height", "depth", "drawer_height", "wall"):
            if not getattr(self, k) > 0:
                raise ValueError(f"CabinetSpec.{k} must be > 0, got {getattr(self, k)}")
        if self.drawer_height >= self.height - 0.2:
            raise ValueError("CabinetSpec.drawer_height leaves no room for the doors")
        for k in ("door_damping", "drawer_damping", "door_friction", "drawer_friction"):
            if getattr(self, k) < 0:
                raise ValueError(f"CabinetSpec.{k} must be >= 0, got {getattr(self, k)}")


def _handle_xml(name: str, centre, vertical: bool, length: float = 0.12) -> str:
    """A bar handle standing 0.04 m off the front (+x), with two posts."""
    r = 0.008
    cx, cy, cz = centre
    bar_size = (2 * r, 2 * r, length) if vertical else (2 * r, length, 2 * r)
    out = [f"<visual name='{name}_bar'><pose>{cx + 0.045:.6g} {cy:.6g} {cz:.6g} 0 0 0</pose>"
           f"{_box(bar_size)}{_material((0.75, 0.75, 0.78, 1))}</visual>",
           f"<collision name='{name}_bar_collision'><pose>{cx + 0.045:.6g} {cy:.6g} "
           f"{cz:.6g} 0 0 0</pose>{_box(bar_size)}</collision>"]
    for s, sign in (("a", -1), ("b", 1)):
        d = sign * (length / 2 - r)
        px, py, pz = (cx + 0.025, cy, cz + d) if vertical else (cx + 0.025, cy + d, cz)
        out.append(f"<visual name='{name}_post_{s}'><pose>{px:.6g} {py:.6g} {pz:.6g} 0 0 0"
                   f"</pose>{_box((0.04, 2 * r, 2 * r))}{_material((0.75, 0.75, 0.78, 1))}"
                   "</visual>")
        out.append(f"<collision name='{name}_post_{s}_collision'><pose>{px:.6g} {py:.6g} "
                   f"{pz:.6g} 0 0 0</pose>{_box((0.04, 2 * r, 2 * r))}</collision>")
    return "".join(out)


def _slab(name: str, centre, size, rgba, collision=True) -> str:
    pose = f"<pose>{_fmt(centre)} 0 0 0</pose>"
    out = f"<visual name='{name}'>{pose}{_box(size)}{_material(rgba)}</visual>"
    if collision:
        out += f"<collision name='{name}_collision'>{pose}{_box(size)}</collision>"
    return out


def _panel_inertia(mass: float, centre, size) -> str:
    a, b, c = size
    return (
        f"<inertial><pose>{_fmt(centre)} 0 0 0</pose><mass>{mass:.6g}</mass><inertia>"
        f"<ixx>{mass * (b * b + c * c) / 12:.6g}</ixx><iyy>{mass * (a * a + c * c) / 12:.6g}"
        f"</iyy><izz>{mass * (a * a + b * b) / 12:.6g}</izz><ixy>0</ixy><ixz>0</ixz><iyz>0"
        "</iyz></inertia></inertial>"
    )


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
    carcass = "".join([
        _slab("top", (-D / 2, 0, H - t / 2), (D, W, t), wood),
        _slab("bottom", (-D / 2, 0, t / 2), (D, W, t), wood),
        _slab("left", (-D / 2, -W / 2 + t / 2, H / 2), (D, t, H), wood),
        _slab("right", (-D / 2, W / 2 - t / 2, H / 2), (D, t, H), wood),
        _slab("back", (-D + t / 2, 0, H / 2), (t, W, H), wood),
        _slab("shelf", (-D / 2, 0, door_h), (D, W, t), wood),
    ])
    links = [
        f"<link name='carcass'>{_panel_inertia(30.0, (-D / 2, 0, H / 2), (D, W, H))}"
        f"{carcass}</link>"
    ]
    joints = ["<joint name='carcass_weld' type='fixed'><parent>world</parent>"
              "<child>carcass</child></joint>"]
    frames = []
    gap, pt = 0.004, 0.018  # door gap to the carcass front, panel thickness
    dw = W / 2 - gap  # width of one door
    dz = door_h - 2 * gap
    x_hinge = gap + pt / 2
    for side, sign in (("left", -1), ("right", 1)):
        body = f"{side}_door"
        # door frame at the hinge: the panel extends along -sign*y from it
        hinge_y = sign * (W / 2)
        pc = (0.0, -sign * dw / 2, dz / 2)
        hy = -sign * (dw - s.handle_offset)
        links.append(
            f"<link name='{body}'><pose>{x_hinge:.6g} {hinge_y:.6g} {gap:.6g} 0 0 0</pose>"
            f"{_panel_inertia(3.0, pc, (pt, dw, dz))}"
            f"{_slab(body + '_panel', pc, (pt, dw, dz), front)}"
            f"{_handle_xml(body + '_handle', (pt / 2, hy, dz * 0.6), vertical=True)}</link>"
        )
        axis = (0, 0, -1) if side == "left" else (0, 0, 1)
        joints.append(_joint_xml(f"{side}_hinge", "revolute", "carcass", body, axis,
                                 0.0, s.door_limit, effort=0, velocity=5,
                                 damping=s.door_damping))
        frames.append(f"<frame name='{body}_handle' attached_to='{body}'>"
                      f"<pose relative_to='{body}'>{pt / 2 + 0.045:.6g} {hy:.6g} "
                      f"{dz * 0.6:.6g} 0 0 0</pose></frame>")
    # drawer: front panel plus a box below/behind it
    dh = s.drawer_height - 2 * gap
    fw = W - 2 * gap
    inner_w, inner_d = W - 2 * t - 0.01, D - 2 * t - 0.02
    drawer_geo = "".join([
        _slab("drawer_front", (0, 0, dh / 2), (pt, fw, dh), front),
        _slab("drawer_bottom", (-inner_d / 2, 0, 0.02), (inner_d, inner_w, 0.01), wood, False),
        _slab("drawer_side_l", (-inner_d / 2, -inner_w / 2, dh / 2 - 0.02),
              (inner_d, 0.01, dh - 0.06), wood, False),
        _slab("drawer_side_r", (-inner_d / 2, inner_w / 2, dh / 2 - 0.02),
              (inner_d, 0.01, dh - 0.06), wood, False),
        _slab("drawer_back", (-inner_d, 0, dh / 2 - 0.02), (0.01, inner_w, dh - 0.06),
              wood, False),
        _handle_xml("drawer_handle", (pt / 2, 0, dh / 2), vertical=False, length=0.16),
    ])
    z_drawer = door_h + gap
    links.append(
        f"<link name='drawer'><pose>{x_hinge:.6g} 0 {z_drawer:.6g} 0 0 0</pose>"
        f"{_panel_inertia(2.5, (-inner_d / 2, 0, dh / 2), (inner_d, inner_w, dh))}"
        f"{drawer_geo}</link>"
    )
    joints.append(_joint_xml("drawer_slide", "prismatic", "carcass", "drawer", (1, 0, 0),
                             0.0, s.drawer_limit, effort=0, velocity=2,
                             damping=s.drawer_damping))
    frames.append(f"<frame name='drawer_handle' attached_to='drawer'><pose relative_to="
                  f"'drawer'>{pt / 2 + 0.045:.6g} 0 {dh / 2:.6g} 0 0 0</pose></frame>")
    return (
        "<?xml version='1.0'?>\n<sdf version='1.9'>"
        f"<model name='{model_name}'>{_model_pose(pose)}" + "".join(links) + "".join(joints)
        + "".join(frames) + "</model></sdf>\n"
    )


def floor_sdf(size: float = 8.0) -> str:
    """A flat floor (box top at z = 0), welded to the world."""
    return (
        "<?xml version='1.0'?>\n<sdf version='1.9'><model name='floor'><static>true</static>"
        f"<link name='floor'><pose>0 0 -0.05 0 0 0</pose>"
        f"<visual name='floor_visual'>{_box((size, size, 0.1))}"
        f"{_material((0.55, 0.55, 0.55, 1))}</visual>"
        f"<collision name='floor_collision'>{_box((size, size, 0.1))}</collision></link>"
        "</model></sdf>\n"
    )


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
    """(Re)write the static SDF files; returns their paths."""
    out = Path(folder) if folder else Path(__file__).resolve().parent
    paths = []
    for fname, build in DEFAULT_MODELS.items():
        p = out / fname
        p.write_text(build())
        paths.append(p)
    return paths


if __name__ == "__main__":
    for p in write_default_models():
        print(p)
