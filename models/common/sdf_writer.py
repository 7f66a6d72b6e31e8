"""One small SDFormat writer, used by every model mmlearn generates.

The robots and furniture (:mod:`mmlearn.sdf.builders`), the articulated test objects
(:mod:`mmlearn.sdf.objects`), the randomised mechanisms (:mod:`mmlearn.sdf.mechanisms`) and
the SDFormat export of learned articulation models (:mod:`mmlearn.models.articulation.io`)
all build their XML here, with :mod:`xml.etree.ElementTree`: names are escaped, every number
of a document goes through one formatter (``digits`` significant digits; non-finite numbers
raise ``ValueError``), and the text is indented.

This module imports nothing from Drake, so ``models/`` may use it (layering: see
ARCHITECTURE.md). Example::

    m = SdfModel("box_on_hinge", pose=(1, 0, 0, 0, 0, 0.5))
    base = m.link("base")
    base.inertial(2.0, box_inertia(2.0, (0.2, 0.2, 0.1)), pose=(0, 0, 0.05))
    base.visual("base_visual", Box((0.2, 0.2, 0.1)), pose=(0, 0, 0.05), color=(1, 0, 0, 1))
    base.collision("base_collision", Box((0.2, 0.2, 0.1)), pose=(0, 0, 0.05))
    m.link("lid", pose=(0, 0, 0.1))
    m.joint("hinge", "revolute", "base", "lid", axis=(0, 1, 0), lower=0, upper=1.5,
            damping=0.1)
    m.frame("lid_handle", attached_to="lid", pose=(0.1, 0, 0.02))
    text = m.to_string()

Supported: model (pose, ``<static>``), links (pose, inertial with mass and inertia
tensor), visuals and collisions with box / cylinder / sphere / capsule / mesh geometry, a
visual's diffuse colour, joints (fixed, revolute, continuous, prismatic, ball) with axis,
limits (lower, upper, effort, velocity) and dynamics (damping, friction, spring reference and
stiffness), frames, XML comments, and any further element (e.g. Drake's
``drake:proximity_properties``) through :meth:`SdfModel.element`. Units: metres, kilograms,
radians, newtons, seconds.

Drake's parser notes: it reads no joint ``<friction>`` (mmlearn applies joint friction in
the scene diagram); a joint without an ``<effort>`` limit gets SDFormat's default (-1,
unlimited) and hence an actuator; a ball joint's damping is read from ``<axis>``, with a
warning that the axis itself is ignored.
"""

from __future__ import annotations

import math
import numbers
import xml.etree.ElementTree as ET
from dataclasses import dataclass

__all__ = [
    "SdfModel", "Link", "Box", "Cylinder", "Sphere", "Capsule", "Mesh", "JOINT_TYPES",
    "box_inertia", "cylinder_inertia",
]

SDF_VERSION = "1.9"
DRAKE_NAMESPACE = "http://drake.mit.edu"
#: joint types the writer knows; the axis-less ones take no <axis>/<xyz>
JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic", "ball")
_AXIS_JOINTS = ("revolute", "continuous", "prismatic")


# ------------------------------------------------------------------------------ geometry
@dataclass(frozen=True)
class Box:
    """Box of edge lengths ``size`` = (x, y, z), m, centred on its frame."""

    size: tuple

    def write(self, m: "SdfModel", geometry: ET.Element) -> None:
        m.element(m.element(geometry, "box"), "size", self.size)


@dataclass(frozen=True)
class Cylinder:
    """Cylinder along its frame's z axis, centred on the frame (m)."""

    radius: float
    length: float
    _tag = "cylinder"

    def write(self, m: "SdfModel", geometry: ET.Element) -> None:
        c = m.element(geometry, self._tag)
        m.element(c, "radius", self.radius)
        m.element(c, "length", self.length)


@dataclass(frozen=True)
class Sphere:
    """Sphere of the given radius (m)."""

    radius: float

    def write(self, m: "SdfModel", geometry: ET.Element) -> None:
        m.element(m.element(geometry, "sphere"), "radius", self.radius)


@dataclass(frozen=True)
class Capsule(Cylinder):
    """Capsule along z: a cylinder of ``length`` (m, without the caps) with hemispherical
    caps of ``radius``."""

    _tag = "capsule"


@dataclass(frozen=True)
class Mesh:
    """Mesh file with an optional per-axis ``scale``: ``uri`` is ``package://...``,
    ``file:///absolute/path`` or (for an SDF parsed from a file) a path relative to it;
    Drake reads .obj (and .gltf) meshes."""

    uri: str
    scale: tuple | None = None

    def write(self, m: "SdfModel", geometry: ET.Element) -> None:
        e = m.element(geometry, "mesh")
        m.element(e, "uri", self.uri)
        if self.scale is not None:
            m.element(e, "scale", self.scale)


def box_inertia(mass: float, size) -> tuple:
    """Principal moments (ixx, iyy, izz) of a solid box of edge lengths ``size``, kg m^2,
    about its centre."""
    a, b, c = (float(v) for v in size)
    return (mass * (b * b + c * c) / 12, mass * (a * a + c * c) / 12, mass * (a * a + b * b) / 12)


def cylinder_inertia(mass: float, radius: float, length: float) -> tuple:
    """Principal moments (ixx, iyy, izz) of a solid cylinder along z about its centre."""
    ixx = mass * (3 * radius**2 + length**2) / 12.0
    return (ixx, ixx, 0.5 * mass * radius**2)


# ------------------------------------------------------------------------------ writer
class Link:
    """A ``<link>`` of an :class:`SdfModel` (made by :meth:`SdfModel.link`)."""

    def __init__(self, model: "SdfModel", element: ET.Element):
        self.model = model
        self.element = element

    @property
    def name(self) -> str:
        return self.element.get("name")

    def inertial(self, mass: float, inertia, *, pose=None) -> ET.Element:
        """Mass (kg) and inertia (kg m^2) about the centre of mass at ``pose``: three
        principal moments (ixx, iyy, izz) or six (ixx, iyy, izz, ixy, ixz, iyz)."""
        inertia = [float(v) for v in inertia]
        if len(inertia) == 3:
            inertia += [0.0, 0.0, 0.0]
        if len(inertia) != 6:
            raise ValueError(f"inertia must have 3 or 6 entries, got {len(inertia)}")
        m = self.model
        e = m.element(self.element, "inertial")
        m.pose(e, pose)
        m.element(e, "mass", mass)
        i = m.element(e, "inertia")
        for tag, v in zip(("ixx", "iyy", "izz", "ixy", "ixz", "iyz"), inertia):
            m.element(i, tag, v)
        return e

    def visual(self, name: str, geometry, *, pose=None, color=None) -> ET.Element:
        """A visual with the given geometry and (optionally) diffuse colour r g b a."""
        e = self._geometry_element("visual", name, geometry, pose)
        if color is not None:
            if len(color) != 4:
                raise ValueError(f"color is r g b a, got {color}")
            self.model.element(self.model.element(e, "material"), "diffuse", color)
        return e

    def collision(self, name: str, geometry, *, pose=None) -> ET.Element:
        """A collision geometry (add Drake proximity properties with
        :meth:`SdfModel.element` on the returned element)."""
        return self._geometry_element("collision", name, geometry, pose)

    def _geometry_element(self, tag, name, geometry, pose) -> ET.Element:
        m = self.model
        e = m.element(self.element, tag, name=name)
        m.pose(e, pose)
        geometry.write(m, m.element(e, "geometry"))
        return e


class SdfModel:
    """One ``<sdf><model>`` document.

    Args:
        name: model name.
        pose: x y z roll pitch yaw (m, rad) of the model frame, or None.
        static: write ``<static>true</static>``.
        digits: significant digits of every number written (``format(x, ".{digits}g")``).

    Links, joints and frames are written in this order (each in the order of the calls),
    whatever the order of the calls; elements added with :meth:`element` to the model
    itself come last.
    """

    def __init__(self, name: str, *, pose=None, static: bool = False, digits: int = 6):
        self.digits = int(digits)
        self.root = ET.Element("sdf", version=SDF_VERSION)
        self.model = ET.SubElement(self.root, "model", name=str(name))
        if pose is not None:
            p = [float(v) for v in pose]
            if len(p) != 6 or not all(math.isfinite(v) for v in p):
                raise ValueError(
                    f"model pose must be 6 finite numbers x y z roll pitch yaw, got {p}")
            self.pose(self.model, p)
        if static:
            self.element(self.model, "static", "true")
        self._sections = {"link": [], "joint": [], "frame": []}

    # -- formatting ---------------------------------------------------------------------
    def num(self, x) -> str:
        """One number as written in this document."""
        v = float(x)
        if not math.isfinite(v):
            raise ValueError(f"SDFormat numbers must be finite, got {x!r}")
        s = format(v, f".{self.digits}g")
        return "0" if s == "-0" else s

    def text(self, value) -> str:
        """Element text: strings as they are, booleans as true/false, a number or a
        sequence of numbers through :meth:`num`."""
        if isinstance(value, str):
            return value
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, numbers.Real):
            return self.num(value)
        return " ".join(self.num(v) for v in value)

    # -- generic elements ---------------------------------------------------------------
    def element(self, parent: ET.Element, tag: str, value=None, **attrib) -> ET.Element:
        """Append ``<tag attrib...>value</tag>`` to ``parent`` (value formatted by
        :meth:`text`; None = no text). A ``drake:`` tag declares Drake's XML namespace."""
        e = ET.SubElement(parent, tag, {k: str(v) for k, v in attrib.items()})
        if value is not None:
            e.text = self.text(value)
        if tag.startswith("drake:"):
            self.root.set("xmlns:drake", DRAKE_NAMESPACE)
        return e

    def pose(self, parent: ET.Element, pose, relative_to: str | None = None):
        """Append ``<pose>`` (x y z, or x y z roll pitch yaw; m, rad) to ``parent``; None
        writes nothing."""
        if pose is None:
            return None
        p = [float(v) for v in pose]
        if len(p) == 3:
            p += [0.0, 0.0, 0.0]
        if len(p) != 6:
            raise ValueError(f"pose must be x y z [roll pitch yaw], got {pose}")
        attrib = {} if relative_to is None else {"relative_to": relative_to}
        return self.element(parent, "pose", p, **attrib)

    @staticmethod
    def comment(parent: ET.Element, text: str) -> None:
        """Put an XML comment first in ``parent``."""
        parent.insert(0, ET.Comment(f" {text.replace('--', '- -')} "))

    # -- model parts --------------------------------------------------------------------
    def link(self, name: str, *, pose=None, relative_to: str | None = None) -> Link:
        """A link at ``pose`` (in the model frame, or in frame ``relative_to``)."""
        e = ET.Element("link", name=str(name))
        self.pose(e, pose, relative_to)
        self._sections["link"].append(e)
        return Link(self, e)

    def joint(self, name: str, type: str, parent: str, child: str, *, pose=None,
              relative_to: str | None = None, axis=None, lower=None, upper=None,
              effort=None, velocity=None, damping=None, friction=None,
              spring_reference=None, spring_stiffness=None) -> ET.Element:
        """A joint of the given type between links ``parent`` (or ``world``) and ``child``.

        ``pose`` places the joint frame (default: in the child link frame). ``axis`` (in
        the joint frame) is required by revolute, continuous and prismatic joints; limits
        (rad or m; effort N m or N; velocity rad/s or m/s) and dynamics (damping N m s/rad
        or N s/m; friction N m or N; spring) are written only when given.
        """
        if type not in JOINT_TYPES:
            raise ValueError(f"joint type must be one of {JOINT_TYPES}, got {type!r}")
        limits = {"lower": lower, "upper": upper, "effort": effort, "velocity": velocity}
        dynamics = {"damping": damping, "friction": friction,
                    "spring_reference": spring_reference, "spring_stiffness": spring_stiffness}
        if type in _AXIS_JOINTS and axis is None:
            raise ValueError(f"a {type} joint needs an axis ({name})")
        if type == "fixed" and (axis is not None or any(v is not None for v in
                                                         (*limits.values(), *dynamics.values()))):
            raise ValueError(f"a fixed joint takes no axis, limits or dynamics ({name})")
        if type == "ball" and axis is not None:
            raise ValueError(f"a ball joint takes no axis ({name})")
        e = ET.Element("joint", name=str(name), type=type)
        self.pose(e, pose, relative_to)
        self.element(e, "parent", str(parent))
        self.element(e, "child", str(child))
        given_limits = {k: v for k, v in limits.items() if v is not None}
        given_dynamics = {k: v for k, v in dynamics.items() if v is not None}
        if axis is not None or given_limits or given_dynamics:
            ax = self.element(e, "axis")
            if axis is not None:
                if len(axis) != 3:
                    raise ValueError(f"axis must be x y z, got {axis}")
                self.element(ax, "xyz", axis)
            for tag, section in (("limit", given_limits), ("dynamics", given_dynamics)):
                if section:
                    s = self.element(ax, tag)
                    for k, v in section.items():
                        self.element(s, k, v)
        self._sections["joint"].append(e)
        return e

    def frame(self, name: str, *, attached_to: str, pose=None,
              relative_to: str | None = None) -> ET.Element:
        """A frame attached to ``attached_to`` at ``pose`` (relative to ``relative_to``;
        SDFormat's default is the attached-to frame)."""
        e = ET.Element("frame", name=str(name), attached_to=str(attached_to))
        self.pose(e, pose, relative_to)
        self._sections["frame"].append(e)
        return e

    # -- output -------------------------------------------------------------------------
    def to_element(self) -> ET.Element:
        """The ``<sdf>`` element tree (a new tree on every call)."""
        root = ET.Element(self.root.tag, self.root.attrib)
        model = ET.SubElement(root, "model", self.model.attrib)
        model.extend(e for e in self.model if e.tag in ("pose", "static"))
        for section in self._sections.values():
            model.extend(section)
        model.extend(e for e in self.model if e.tag not in ("pose", "static"))
        return root

    def to_string(self) -> str:
        """The document as text (XML declaration, two-space indentation, final newline)."""
        root = self.to_element()
        ET.indent(root, "  ")
        return "<?xml version='1.0'?>\n" + ET.tostring(root, encoding="unicode") + "\n"
