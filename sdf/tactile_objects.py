"""The objects of the tactile recognition experiment (thesis ch. 6, Sec. 6.3): 16 objects,
21 classes, as SDFormat with hydroelastic contact (generated with
:mod:`mmlearn.models.common.sdf_writer`).

The thesis grasped 5 industrial parts "with a relatively similar shape" and 11 household
objects ("cups, toys, and bottles", a tennis ball and a soft ball of the same size), some of
them under 0 and 90 deg rotation, 21 class labels in all. The objects here follow that
description (the thesis gives no dimensions; these are those of common products and
aluminium / steel stock):

============== ========== ============================================================ =======
object         group      shape (m)                                                    yaw deg
============== ========== ============================================================ =======
profile_a      industrial 40 x 40 T-slot profile, 8 mm slots on all four faces, 0.10    0
profile_b      industrial the same profile with slots on the two y faces only        0, 90
block_hole     industrial 42 x 42 x 100 steel block, 10 x 10 mm cross hole at 50 mm     0, 90
round_bar      industrial 40 mm steel bar, 0.10 long, a 3.5 mm deep groove at 60-70 mm  0
stepped_shaft  industrial 40 mm shaft stepped down to 30 mm above 50 mm                 0
bottle         household  PET bottle 65 mm, two grooves, shoulder, neck, cap            0
can            household  aluminium can 66 x 122 mm with its necked top                 0
mug            household  ceramic mug 82 x 95 mm with a handle (touched at 90 deg)      0, 90
tumbler        household  glass tumbler widening from 68 to 74 mm at half height        0
tea_box        household  cardboard box 60 x 95 x 150 mm                                0, 90
soft_ball      household  foam ball 67 mm                                              0
tennis_ball    household  tennis ball 67 mm                                             0
spray_can      household  45 mm spray can with a 43 mm cap                              0
wine_glass     household  foot, 8 mm stem, 80 mm bowl                                   0
sponge         household  foam sponge 45 x 70 x 95 mm                                   0, 90
rubber_toy     household  rubber toy: ellipsoid body and a head off the axis            0
============== ========== ============================================================ =======

Object frame: origin on the vertical axis at the bottom, z up. The gripper closes along the
world x axis, so ``yaw`` (the rotation about z) decides which faces the fingers touch; at
yaw 0 the mug's handle points along +y (not touched; at 90 deg it points along -x and the
left finger closes on it), profile_b shows the fingers its two flat faces (at 90 deg the
slotted ones, which look like profile_a), block_hole's hole runs along x (the fingers feel
it at 45-55 mm; at 90 deg they touch two intact faces, which look like profile_b at 0 deg
but 2 mm wider), and the tea box and sponge are squeezed across their narrow side (at 90
deg across the wide one).

**Materials** (:data:`MATERIALS`): metal, glass and ceramic are *rigid* hydroelastic (the
compliant taxel pads take the deformation); plastic, cardboard, rubber and foam are
*compliant* hydroelastic with an effective hydroelastic modulus E (Pa; Drake's pressure
field ``p = E * depth / (half the smallest extent)``), so that under the ~15 N grasp a PET
bottle or a cardboard box yields a little, the tennis ball ~2 mm per side and the foam ball
or sponge 10-15 mm: soft and hard objects of the same size give different tactile images
and finger distances. The pads themselves are compliant (E = 1 MPa, see
:mod:`mmlearn.sdf.tactile`).

**Variation** (:func:`sample_object`, seeded): every instance scales all lengths by
``exp(N(0, 0.01))``, the hydroelastic modulus of compliant parts by ``exp(N(0, 0.15))``,
the friction coefficient by ``exp(N(0, 0.1))`` and the mass by ``exp(N(0, 0.05))``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from mmlearn.models.common.sdf_writer import Box, Cylinder, SdfModel, Sphere, box_inertia

__all__ = ["Material", "MATERIALS", "Part", "TactileObject", "OBJECTS", "CLASSES",
           "ObjectClass", "class_of", "sample_object", "object_sdf", "Ellipsoid", "GROUPS"]

GROUPS = ("household", "industrial")


@dataclass(frozen=True)
class Ellipsoid:
    """Ellipsoid with semi-axes ``radii`` (a, b, c) along x, y, z, m (SDFormat 1.9)."""

    radii: tuple

    def write(self, m: SdfModel, geometry) -> None:
        e = m.element(geometry, "ellipsoid")
        m.element(e, "radii", self.radii)


@dataclass(frozen=True)
class Material:
    """Contact material.

    Attributes:
        modulus: hydroelastic modulus E, Pa; None: rigid hydroelastic.
        mu: Coulomb friction coefficient (static = dynamic).
        density: kg/m^3 of the solid (for the mass; hollow objects set their mass).
        resolution: mesh resolution hint of compliant geometry, m.
        dissipation: Hunt-Crossley dissipation, s/m.
        color: r g b a of the visual.
    """

    modulus: float | None
    mu: float
    density: float
    resolution: float = 0.005
    dissipation: float = 5.0
    color: tuple = (0.7, 0.7, 0.7, 1.0)


#: Effective contact materials (see the module docstring). Moduli are "effective": they
#: lump the wall's bending with the material (a thin PET wall yields far more than bulk PET).
MATERIALS = {
    "aluminium": Material(None, 0.4, 2700.0, color=(0.75, 0.76, 0.78, 1)),
    "steel": Material(None, 0.35, 7850.0, color=(0.55, 0.56, 0.6, 1)),
    "glass": Material(None, 0.5, 2500.0, color=(0.8, 0.9, 0.95, 0.6)),
    "ceramic": Material(None, 0.6, 2300.0, color=(0.95, 0.95, 0.9, 1)),
    "pet": Material(3.0e6, 0.5, 1380.0, color=(0.6, 0.8, 1.0, 0.7)),
    "pp": Material(2.0e7, 0.5, 900.0, color=(0.2, 0.3, 0.8, 1)),
    "can_alu": Material(1.0e7, 0.4, 2700.0, color=(0.8, 0.1, 0.1, 1)),
    "cardboard": Material(2.0e6, 0.6, 700.0, color=(0.85, 0.7, 0.45, 1)),
    "rubber": Material(3.0e5, 0.9, 1100.0, resolution=0.006, color=(1.0, 0.85, 0.1, 1)),
    "tennis": Material(2.0e6, 0.8, 400.0, resolution=0.006, color=(0.8, 0.95, 0.2, 1)),
    "foam": Material(5.0e4, 0.9, 60.0, resolution=0.008, color=(1.0, 0.5, 0.2, 1)),
    "sponge": Material(3.0e4, 0.9, 40.0, resolution=0.008, color=(0.3, 0.8, 0.3, 1)),
}


@dataclass(frozen=True)
class Part:
    """One primitive of an object: ``kind`` "box" (size x y z), "cylinder" (radius,
    length along z), "sphere" (radius,) or "ellipsoid" (a, b, c); its centre at ``xyz``
    (m, object frame) turned by ``yaw`` (rad) about z; ``material`` a key of
    :data:`MATERIALS`."""

    kind: str
    dims: tuple
    xyz: tuple
    material: str
    yaw: float = 0.0


@dataclass(frozen=True)
class TactileObject:
    """One object of the experiment.

    Attributes:
        name: object name.
        group: "household" or "industrial".
        parts: its primitives (non-overlapping where the pads can touch).
        mass: nominal mass, kg.
        heights: (lowest, highest) grasp height of the pad centre above the object's
            bottom, m (the range the robot's grasps cover, bottom to top).
        yaws: rotations about z the object is grasped under, deg (one class each).
    """

    name: str
    group: str
    parts: tuple
    mass: float
    heights: tuple
    yaws: tuple = (0,)


def _stack(radii_z, material, x=0.0):
    """Coaxial cylinders: [(radius, z0, z1), ...] -> parts."""
    return tuple(Part("cylinder", (r, z1 - z0), (x, 0.0, 0.5 * (z0 + z1)), material)
                 for r, z0, z1 in radii_z)


def _profile(name, slotted_x: bool, slotted_y: bool, *, a=0.02, slot=0.004, depth=0.004,
             height=0.10, material="aluminium", group="industrial", yaws=(0,)):
    """A square profile of half width ``a`` with (or without) a slot of half width ``slot``
    and ``depth`` in the middle of the +-x and +-y faces; decomposed into a core and lips
    that do not overlap."""
    zc, h = height / 2, height
    c = a - depth
    parts = [Part("box", (2 * c, 2 * c, h), (0, 0, zc), material)]
    for s in (-1.0, 1.0):
        # x faces: the lips span the full y range (corners included)
        if slotted_x:
            w = a - slot
            for t in (-1.0, 1.0):
                parts.append(Part("box", (depth, w, h),
                                  (s * (c + depth / 2), t * (slot + w / 2), zc), material))
        else:
            parts.append(Part("box", (depth, 2 * a, h), (s * (c + depth / 2), 0, zc), material))
        # y faces: lips between the x lips
        if slotted_y:
            w = c - slot
            for t in (-1.0, 1.0):
                parts.append(Part("box", (w, depth, h),
                                  (t * (slot + w / 2), s * (c + depth / 2), zc), material))
        else:
            parts.append(Part("box", (2 * c, depth, h), (0, s * (c + depth / 2), zc), material))
    # an aluminium 40 x 40 profile weighs about 1.5 kg per metre
    return TactileObject(name, group, tuple(parts), mass=1.5 * height,
                         heights=(0.03, height - 0.03), yaws=yaws)


def _block_hole():
    a, hh, z0, z1, H = 0.021, 0.005, 0.045, 0.055, 0.10
    m = "steel"
    parts = (Part("box", (2 * a, 2 * a, z0), (0, 0, z0 / 2), m),
             Part("box", (2 * a, 2 * a, H - z1), (0, 0, (z1 + H) / 2), m),
             # the hole runs along x at yaw 0: side walls left and right of it (along y)
             Part("box", (2 * a, a - hh, z1 - z0), (0, -(hh + (a - hh) / 2), (z0 + z1) / 2), m),
             Part("box", (2 * a, a - hh, z1 - z0), (0, hh + (a - hh) / 2, (z0 + z1) / 2), m))
    return TactileObject("block_hole", "industrial", parts, mass=1.36, heights=(0.03, 0.07),
                         yaws=(0, 90))


def _mug():
    R, H = 0.041, 0.095
    m = "ceramic"
    # the handle points along +y at yaw 0: a vertical bar and two arms
    bar_y, t = R + 0.018, 0.010
    parts = _stack([(R, 0.0, H)], m) + (
        Part("box", (0.012, t, 0.06), (0, bar_y, 0.05), m),
        Part("box", (0.012, bar_y - R - t / 2 + 0.002, 0.008),
             (0, (R - 0.002 + bar_y - t / 2) / 2, 0.076), m),
        Part("box", (0.012, bar_y - R - t / 2 + 0.002, 0.008),
             (0, (R - 0.002 + bar_y - t / 2) / 2, 0.024), m))
    return TactileObject("mug", "household", parts, mass=0.32, heights=(0.02, 0.08),
                         yaws=(0, 90))


def _catalog() -> dict:
    objs = [
        _profile("profile_a", True, True),
        _profile("profile_b", False, True, yaws=(0, 90)),
        _block_hole(),
        TactileObject("round_bar", "industrial",
                      _stack([(0.02, 0.0, 0.06), (0.0165, 0.06, 0.07), (0.02, 0.07, 0.10)],
                             "steel"), mass=0.96, heights=(0.03, 0.07)),
        TactileObject("stepped_shaft", "industrial",
                      _stack([(0.02, 0.0, 0.05), (0.015, 0.05, 0.10)], "steel"), mass=0.77,
                      heights=(0.03, 0.07)),
        TactileObject("bottle", "household",
                      _stack([(0.0325, 0.0, 0.045), (0.030, 0.045, 0.051),
                              (0.0325, 0.051, 0.095), (0.030, 0.095, 0.101),
                              (0.0325, 0.101, 0.15), (0.024, 0.15, 0.175),
                              (0.0135, 0.175, 0.195)], "pet")
                      + _stack([(0.0155, 0.195, 0.21)], "pp"),
                      mass=0.52, heights=(0.03, 0.19)),
        TactileObject("can", "household",
                      _stack([(0.033, 0.0, 0.11), (0.029, 0.11, 0.118), (0.027, 0.118, 0.122)],
                             "can_alu"), mass=0.37, heights=(0.03, 0.11)),
        _mug(),
        TactileObject("tumbler", "household",
                      _stack([(0.034, 0.0, 0.06), (0.037, 0.06, 0.12)], "glass"), mass=0.3,
                      heights=(0.03, 0.11)),
        TactileObject("tea_box", "household",
                      (Part("box", (0.06, 0.095, 0.15), (0, 0, 0.075), "cardboard"),),
                      mass=0.1, heights=(0.03, 0.13), yaws=(0, 90)),
        TactileObject("soft_ball", "household",
                      (Part("sphere", (0.0335,), (0, 0, 0.0335), "foam"),), mass=0.01,
                      heights=(0.02, 0.05)),
        TactileObject("tennis_ball", "household",
                      (Part("sphere", (0.0335,), (0, 0, 0.0335), "tennis"),), mass=0.058,
                      heights=(0.02, 0.05)),
        TactileObject("spray_can", "household",
                      _stack([(0.0225, 0.0, 0.15), (0.019, 0.15, 0.16)], "aluminium")
                      + _stack([(0.0215, 0.16, 0.20)], "pp"), mass=0.25, heights=(0.03, 0.19)),
        TactileObject("wine_glass", "household",
                      _stack([(0.035, 0.0, 0.004), (0.004, 0.004, 0.08), (0.04, 0.08, 0.17)],
                             "glass"), mass=0.2, heights=(0.03, 0.16)),
        TactileObject("sponge", "household",
                      (Part("box", (0.045, 0.07, 0.095), (0, 0, 0.0475), "sponge"),),
                      mass=0.015, heights=(0.03, 0.07), yaws=(0, 90)),
        TactileObject("rubber_toy", "household",
                      (Part("ellipsoid", (0.045, 0.035, 0.032), (0, 0, 0.032), "rubber"),
                       Part("sphere", (0.022,), (0.018, 0, 0.084), "rubber")),
                      mass=0.08, heights=(0.02, 0.09)),
    ]
    return {o.name: o for o in objs}


#: The 16 objects by name.
OBJECTS: dict = _catalog()


@dataclass(frozen=True)
class ObjectClass:
    """A class label: an object grasped under one rotation ``yaw`` (deg)."""

    name: str
    object: str
    yaw: int
    group: str


def _classes() -> dict:
    out = {}
    for o in OBJECTS.values():
        for y in o.yaws:
            name = o.name if len(o.yaws) == 1 else f"{o.name}@{y}"
            out[name] = ObjectClass(name, o.name, int(y), o.group)
    return out


#: The 21 class labels (object, or object@yaw for objects grasped under two rotations).
CLASSES: dict = _classes()


def class_of(name: str) -> ObjectClass:
    """The :class:`ObjectClass` of a label; ValueError naming the known ones."""
    if name not in CLASSES:
        raise ValueError(f"unknown tactile object class {name!r}; choose from "
                         f"{', '.join(CLASSES)}")
    return CLASSES[name]


@dataclass(frozen=True)
class ObjectInstance:
    """One physical instance (the object's parts scaled and its materials varied).

    Attributes:
        name: object name; yaw: rotation about z, deg.
        parts: the scaled parts (already turned by ``yaw``).
        scale: length scale factor; mass: kg; mu_scale: factor on every friction
        coefficient; modulus_scale: factor on every compliant hydroelastic modulus.
        group: "household" or "industrial".
    """

    name: str
    yaw: float
    parts: tuple
    scale: float
    mass: float
    mu_scale: float
    modulus_scale: float
    group: str = ""

    def as_dict(self) -> dict:
        return {"name": self.name, "yaw": self.yaw, "scale": self.scale, "mass": self.mass,
                "mu_scale": self.mu_scale, "modulus_scale": self.modulus_scale}


def sample_object(name: str, rng: np.random.Generator | None = None, *, yaw: float = 0.0,
                  nominal: bool = False) -> ObjectInstance:
    """A random instance of object ``name`` turned by ``yaw`` deg about z (seeded through
    ``rng``; ``nominal``: no variation)."""
    if name not in OBJECTS:
        raise ValueError(f"unknown tactile object {name!r}; choose from {', '.join(OBJECTS)}")
    if not np.isfinite(yaw):
        raise ValueError(f"yaw: expected a finite angle in degrees, got {yaw!r}")
    o = OBJECTS[name]
    if nominal:
        s = mu = ms = E = 1.0
    else:
        if rng is None:
            raise ValueError("sample_object: give rng (or nominal=True)")
        s, mu, ms, E = np.exp(rng.normal(0.0, [0.01, 0.1, 0.05, 0.15]))
    c, si = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    parts = []
    for p in o.parts:
        x, y, z = p.xyz
        parts.append(replace(p, dims=tuple(float(d * s) for d in p.dims),
                             xyz=(float(s * (c * x - si * y)), float(s * (si * x + c * y)),
                                  float(s * z)),
                             yaw=float(p.yaw + math.radians(yaw))))
    return ObjectInstance(name, float(yaw), tuple(parts), float(s), float(o.mass * ms),
                          float(mu), float(E), group=o.group)


def _geometry(p: Part):
    if p.kind == "box":
        return Box(p.dims)
    if p.kind == "cylinder":
        return Cylinder(p.dims[0], p.dims[1])
    if p.kind == "sphere":
        return Sphere(p.dims[0])
    if p.kind == "ellipsoid":
        return Ellipsoid(tuple(p.dims))
    raise ValueError(f"part kind {p.kind!r}: expected box, cylinder, sphere or ellipsoid")


def object_sdf(inst: ObjectInstance, *, model_name: str = "object") -> str:
    """The instance as SDFormat text: one link ``base`` (origin at the bottom on the axis)
    with one visual and one hydroelastic collision per part."""
    m = SdfModel(model_name)
    b = m.link("base")
    hmax = max(p.xyz[2] + (p.dims[-1] / 2 if p.kind in ("box", "cylinder") else p.dims[-1])
               for p in inst.parts)
    # inertia of a box of the object's bounding size: the object is welded in the
    # experiment, the mass is there for completeness (e.g. a wrist sensor)
    w = 2 * max(max(abs(p.xyz[0]), abs(p.xyz[1])) + max(p.dims[:2] if p.kind == "box"
                                                       else p.dims[:1]) for p in inst.parts)
    b.inertial(inst.mass, box_inertia(inst.mass, (w, w, hmax)), pose=(0, 0, hmax / 2))
    for i, p in enumerate(inst.parts):
        mat = MATERIALS[p.material]
        pose = (*p.xyz, 0.0, 0.0, p.yaw)
        geo = _geometry(p)
        b.visual(f"part{i}_visual", geo, pose=pose, color=mat.color)
        col = b.collision(f"part{i}", geo, pose=pose)
        pp = m.element(col, "drake:proximity_properties")
        if mat.modulus is None:
            m.element(pp, "drake:rigid_hydroelastic")
        else:
            m.element(pp, "drake:compliant_hydroelastic")
            m.element(pp, "drake:hydroelastic_modulus", mat.modulus * inst.modulus_scale)
            m.element(pp, "drake:hunt_crossley_dissipation", mat.dissipation)
        # SAP's Kelvin-Voigt time scale, s: Drake's default (0.1 s) makes the elastic
        # pressure the taxels read differ from the contact force (measured: a flat rigid
        # face read 31 N for a 15 N grasp); 2 ms as the pads (mmlearn.sdf.tactile)
        m.element(pp, "drake:relaxation_time", 0.002)
        m.element(pp, "drake:mesh_resolution_hint", mat.resolution)
        m.element(pp, "drake:mu_dynamic", mat.mu * inst.mu_scale)
        m.element(pp, "drake:mu_static", mat.mu * inst.mu_scale)
    return m.to_string()
