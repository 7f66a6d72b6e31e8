"""SDFormat for the tactile experiments (ch. 6-7): a parallel two-finger gripper with
compliant hydroelastic taxel pads, and containers with compliant walls (generated with
:mod:`mmlearn.models.common.sdf_writer`).

Gripper frame G (the model frame): the fingers close along x, hang down along -z from the
palm at the origin; the pad surfaces are centred at z = -``pad_z`` (m). Finger joints are
prismatic, ``left_slide`` along +x and ``right_slide`` along -x, so each joint position is
that finger's closure (m, 0 = fully open) and the distance between the pad surfaces is
``open_gap - q_left - q_right``.

Container frame: origin on the axis at the bottom; the two wall patches face -x (``wall_l``)
and +x (``wall_r``) and move inward on prismatic joints (``wall_l_slide`` along +x,
``wall_r_slide`` along -x; the spring and damper are added by the diagram, see
:mod:`mmlearn.models.tactile.containers`).
"""

from __future__ import annotations

from dataclasses import dataclass

from mmlearn.models.tactile.containers import ContainerInstance
from mmlearn.models.tactile.pad import PadLayout

from mmlearn.models.common.sdf_writer import Box, Cylinder, SdfModel, box_inertia, cylinder_inertia

__all__ = ["GripperGeometry", "gripper_sdf", "container_sdf", "block_sdf", "pad_z_of"]


@dataclass(frozen=True)
class GripperGeometry:
    """Dimensions of the parallel gripper.

    Attributes:
        open_gap: distance between the pad surfaces when fully open, m.
        stroke: closure range of each finger, m.
        finger_length: finger length below the palm, m.
        finger_mass: mass of each finger, kg.
        pad_thickness: thickness of the compliant pad layer, m.
        pad_modulus: hydroelastic modulus of the pads, Pa.
        pad_dissipation: Hunt-Crossley dissipation of the pads, s/m.
        mu: pad friction coefficient.
        effort: actuator force limit of each finger, N (PR2: software limit 100 N).
    """

    open_gap: float = 0.09
    stroke: float = 0.045
    finger_length: float = 0.07
    finger_mass: float = 0.05
    pad_thickness: float = 0.004
    pad_modulus: float = 1.0e6
    pad_dissipation: float = 5.0
    mu: float = 0.8
    effort: float = 100.0


def _hydro(m: SdfModel, collision, *, modulus=None, resolution=None, mu=0.6,
           dissipation=None, rigid=False, relaxation_time=0.002):
    pp = m.element(collision, "drake:proximity_properties")
    if rigid:
        m.element(pp, "drake:rigid_hydroelastic")
    else:
        m.element(pp, "drake:compliant_hydroelastic")
        m.element(pp, "drake:hydroelastic_modulus", modulus)
    if resolution is not None:
        m.element(pp, "drake:mesh_resolution_hint", resolution)
    if dissipation is not None:
        m.element(pp, "drake:hunt_crossley_dissipation", dissipation)
    if relaxation_time is not None:  # SAP's Kelvin-Voigt time scale, s (default 0.1 s
        # makes the elastic pressure -- what a taxel reads -- lag the contact force)
        m.element(pp, "drake:relaxation_time", relaxation_time)
    m.element(pp, "drake:mu_dynamic", mu)
    m.element(pp, "drake:mu_static", mu)


def gripper_sdf(layout: PadLayout, geom: GripperGeometry = GripperGeometry(), *,
                name: str = "gripper") -> str:
    """The gripper as SDFormat text; pads of ``layout`` (length along z, width along y)."""
    m = SdfModel(name)
    palm = m.link("palm")
    palm_size = (geom.open_gap + 0.04, 0.04, 0.02)
    palm.inertial(0.3, box_inertia(0.3, palm_size), pose=(0, 0, 0.01))
    palm.visual("palm_visual", Box(palm_size), pose=(0, 0, 0.01), color=(0.3, 0.3, 0.35, 1))
    fw = max(layout.width + 0.004, 0.02)
    fl = geom.finger_length
    pad_z = fl - layout.length / 2 - 0.004
    for side, sgn in (("left", -1.0), ("right", 1.0)):
        x_surf = sgn * geom.open_gap / 2  # pad surface when open
        body = m.link(f"{side}_finger", pose=(x_surf, 0, 0))
        size = (0.008, fw, fl)
        cx = sgn * (geom.pad_thickness + 0.004)
        body.inertial(geom.finger_mass, box_inertia(geom.finger_mass, size), pose=(cx, 0, -fl / 2))
        body.visual(f"{side}_finger_visual", Box(size), pose=(cx, 0, -fl / 2),
                    color=(0.5, 0.5, 0.55, 1))
        pad = (geom.pad_thickness, layout.width, layout.length)
        pose = (sgn * geom.pad_thickness / 2, 0, -pad_z)
        body.visual(f"{side}_pad_visual", Box(pad), pose=pose, color=(0.15, 0.15, 0.15, 1))
        col = body.collision(f"{side}_pad", Box(pad), pose=pose)
        _hydro(m, col, modulus=geom.pad_modulus, resolution=0.002, mu=geom.mu,
               dissipation=geom.pad_dissipation)
        m.joint(f"{side}_slide", "prismatic", "palm", f"{side}_finger",
                axis=(-sgn, 0, 0), lower=0.0, upper=geom.stroke, effort=geom.effort,
                velocity=0.5)
        m.frame(f"{side}_pad_frame", attached_to=f"{side}_finger", pose=(0, 0, -pad_z))
    return m.to_string()


def pad_z_of(layout: PadLayout, geom: GripperGeometry = GripperGeometry()) -> float:
    """Depth of the pad centres below the palm, m."""
    return geom.finger_length - layout.length / 2 - 0.004


def container_sdf(inst: ContainerInstance, *, name: str = "container",
                  wall_height: float = 0.08, mu: float = 0.5) -> str:
    """A container instance as SDFormat: a base (visual: the whole container) and two wall
    patches on prismatic joints. Each wall's contact geometry is a vertical cylinder of half
    the container's radius whose outer side lies on the container's surface (a stand-in for
    the curved wall; the two never touch each other: a collision filter group)."""
    m = SdfModel(name)
    R, H = inst.radius, inst.height
    base = m.link("base")
    mb = max(inst.mass - 2 * inst.wall_mass - inst.slosh_mass, 0.01)
    base.inertial(mb, cylinder_inertia(mb, R, H), pose=(0, 0, H / 2))
    colour = {"odwalla": (0.95, 0.6, 0.1, 0.6), "naked": (0.2, 0.7, 0.2, 0.6),
              "can": (0.8, 0.1, 0.1, 0.6), "water": (0.6, 0.8, 1.0, 0.4)}.get(
        inst.name, (0.7, 0.7, 0.7, 0.6))
    base.visual("body_visual", Cylinder(R * 0.97, H), pose=(0, 0, H / 2), color=colour)
    zc = H / 2
    r = R / 2
    for side, sgn in (("l", -1.0), ("r", 1.0)):
        w = m.link(f"wall_{side}")
        mw = max(inst.wall_mass, 1e-3)
        w.inertial(mw, cylinder_inertia(mw, r, wall_height), pose=(sgn * r, 0, zc))
        w.visual(f"wall_{side}_visual", Cylinder(r, wall_height), pose=(sgn * r, 0, zc),
                 color=colour)
        col = w.collision(f"wall_{side}_collision", Cylinder(r, wall_height),
                          pose=(sgn * r, 0, zc))
        _hydro(m, col, resolution=0.003, mu=mu, rigid=True)
        m.joint(f"wall_{side}_slide", "prismatic", "base", f"wall_{side}",
                axis=(-sgn, 0, 0), lower=-0.002, upper=0.6 * R, damping=inst.c, effort=0)
    if inst.slosh_mass > 0:
        s = m.link("liquid")
        s.inertial(inst.slosh_mass, (1e-5, 1e-5, 1e-5), pose=(0, 0, zc))
        travel = inst.slosh_travel if inst.slosh_travel > 0 else 0.5 * R
        m.joint("slosh", "prismatic", "base", "liquid", axis=(1, 0, 0), lower=-travel,
                upper=travel, damping=inst.slosh_c, effort=0)
    g = m.element(m.model, "drake:collision_filter_group", name="container_self")
    for lk in ("base", "wall_l", "wall_r"):
        m.element(g, "drake:member", lk)
    m.element(g, "drake:ignored_collision_filter_group", "container_self")
    return m.to_string()


def block_sdf(size=(0.04, 0.1, 0.12), *, name: str = "block", modulus: float | None = None,
              mass: float = 0.2, mu: float = 0.6) -> str:
    """A box standing on z = 0 (e.g. the wooden block of Fig. 7.5): rigid hydroelastic, or
    compliant with hydroelastic ``modulus`` (Pa; a rubber toy ~1e5-1e6)."""
    m = SdfModel(name)
    b = m.link("base")
    b.inertial(mass, box_inertia(mass, size), pose=(0, 0, size[2] / 2))
    b.visual("visual", Box(size), pose=(0, 0, size[2] / 2), color=(0.7, 0.5, 0.3, 1))
    col = b.collision("collision", Box(size), pose=(0, 0, size[2] / 2))
    _hydro(m, col, modulus=modulus, rigid=modulus is None, mu=mu)
    return m.to_string()
