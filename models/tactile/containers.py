"""Containers with an internal state (thesis ch. 7): the lumped physics behind the squeeze.

Plain numpy. A container is a rigid base with two compliant wall patches facing the fingers,
each on a prismatic joint along the squeeze direction (x, inward positive) with a linear
spring, a damper and a lumped mass. The spring of each wall is the sum of

* the **shell** stiffness ``k_wall`` (N/m): bending of the container wall, from the material;
* the **gas** stiffness of a closed container: pushing both walls in by x reduces the
  enclosed volume by ``2 A x`` (``A`` the wall area swept per unit displacement, m^2); the
  pressure rises by ``dp = 2 A x / C`` with the total compliance
  ``C = V_gas / p0 + C_shell`` (m^3/Pa: the isothermal ideal-gas headspace ``V_gas / p0``
  plus the bulging of the rest of the shell ``C_shell``), and acts on the wall with ``A dp``:
  ``k_gas = 2 A^2 / C`` per wall (exact for a symmetric squeeze, which the two-finger grasp
  is). A full closed container has a small headspace and so resists; an empty closed one
  is an air spring; an open one vents (``k_gas = 0``);
* the **hydrostatic** stiffness of an open full container: the displaced liquid rises in the
  neck of area ``A_neck``: ``k_hyd = 2 A^2 rho g / A_neck``.

Liquid moves with the wall: a full container adds the liquid's added mass
``rho L_neck A^2 / A_neck`` (the liquid column accelerated in the neck, open or closed) and a
viscous damping ``c_liq`` (N s/m, from the liquid's viscosity) to each wall. A liquid's bulk
also sloshes: ``slosh_mass`` (kg) on a spring-damper (``slosh_k`` N/m, ``slosh_c`` N s/m) in
the base (its frequency and damping follow a first sloshing mode; used when the container
moves, e.g. liquid detection). Numbers per class are in :data:`CONTAINER_CLASSES`; each
instance draws its own values around them (seeded: sizes +-1 %, stiffnesses and compliances
by the class' ``spread``, fill level 88-97 % when full).

The constant ``A`` above is the **linearised** model (``ContainerInstance.k``, still used by
the liquid-detection roll, :mod:`mmlearn.diagrams.tactile.liquid_roll`). The probing grasp of
Sec. 7.1 (:mod:`mmlearn.diagrams.tactile.grasp`, ``wall_model="pressure"``) uses the
**squeeze-volume model** of :func:`squeeze_pressure` / :func:`wall_forces` instead: a round
bottle pinched by a total ``d`` (the two walls' inward travel, m) first ovalises, which changes
its cross-section only at second order (an ellipse of semi-axes ``R - d/2``, ``R + d/2`` has
the area ``pi (R^2 - d^2 / 4)``), so the enclosed volume drops by

    ``dV(d) = pi L d^2 / 4``  (m^3; ``L`` the length of the ovalised zone, ``squeeze_length``)

and the wall feels the content only through ``dV``: the content's pressure rise ``dp`` acts on
each wall with the generalized force ``dp * dV'(d)`` (virtual work; ``dV'(d) = pi L d / 2``,
m^2). ``dp`` is the exact isothermal gas law of the closed headspace with the rest of the shell
bulging (``p0 V_gas = (p0 + dp) (V_gas - dV + C_shell dp)``, solved in closed form), the
hydrostatic head ``rho g min(dV, V_gas) / A_neck`` of an open full container (the liquid
rises in the neck until it spills over the rim), 0 for an open empty one. A
full container's liquid resists the volume flow ``Q = dV'(d) d'`` with ``R_liq Q`` (Pa;
``R_liq = c_liq / A^2`` so that at ``dV' = A`` it matches the linearised damping). Both grow
with the squeeze: at a light probe the shell's own (linear) stiffness dominates and the states
look alike, a harder probe presses the content and separates them (thesis Table 7.2). Drake
side: :class:`mmlearn.systems.tactile.container_wall.ContainerWallForce`.

**Grasp-to-grasp variation** (:func:`vary_grasp`). The thesis grasped few containers many
times ("we rotated the containers between taking measurements to account for variations in
surface properties of individual containers"): the same bottle yields differently from grasp
to grasp as the pads land on the label, a seam or a rib, higher or lower on it, and as its
thin shell responds. :func:`vary_grasp` draws, per grasp, a log-normal factor
``exp(N(0, grasp_spread))`` (the class' ``grasp_spread``) on the whole static response of both
wall patches (the shell stiffness and, through the ovalised length, the content's coupling:
"wall", the default; "shell" scales the shell alone), on top of the instance's own draw. ``grasp_spread`` is measured, not chosen: the relative spread
of the squeeze over ten repeated grasps of the same object in the same state by the iCub hand
(``benchmarks/bench_grasp_variation.py`` on the shared iCub grasp data: the sd of the final
closure beyond the lotion bottle's 0.25 deg, over the mean squeeze): 0.131 for the plastic
(vitamin-water) bottle, half-full and full pooled, applied to the three plastic bottle classes;
0.248 for the soda can, empty and half-full pooled. What was measured is the spread of the
squeeze of filled bottles and cans, so the "wall" mode scales their whole response (the shell
alone would leave a closed bottle, whose gas carries most of the load, almost unvaried). The
content itself (fill, gas volume) is the same from grasp to grasp.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

__all__ = ["ContainerClass", "ContainerInstance", "CONTAINER_CLASSES", "STATES",
           "states_of", "sample_container", "vary_grasp", "GRASP_VARIATIONS",
           "ICUB_SPREAD_PLASTIC_BOTTLE", "ICUB_SPREAD_CAN", "P0", "RHO_WATER", "G",
           "squeeze_volume", "squeeze_pressure", "wall_forces"]

P0 = 101325.0  # Pa, atmospheric pressure
RHO_WATER = 1000.0  # kg/m^3
G = 9.81  # m/s^2

STATES = ("full_closed", "full_open", "empty_open", "empty_closed")

#: relative grasp-to-grasp spread of the squeeze of the same container in the same state,
#: measured on the real iCub grasps (``benchmarks/bench_grasp_variation.py``): the plastic
#: (vitamin-water) bottle, half-full and full pooled, and the soda can, empty and half-full
ICUB_SPREAD_PLASTIC_BOTTLE = 0.131
ICUB_SPREAD_CAN = 0.248

#: ``vary_grasp`` modes: "none" (every grasp of an instance alike), "wall"
#: (a per-grasp draw of the wall's whole static response, shell and content coupling, with the
#: class' ``grasp_spread``) and "shell" (of the shell stiffness alone)
GRASP_VARIATIONS = ("none", "wall", "shell")


@dataclass(frozen=True)
class ContainerClass:
    """Nominal numbers of one kind of container.

    Attributes:
        name: class name.
        radius: outer radius at the grasp, m.
        height: height, m.
        volume: inner volume, m^3.
        k_wall: shell stiffness of one wall patch, N/m.
        area: wall area swept per unit inward displacement, m^2.
        c_shell: pressure compliance of the rest of the shell, m^3/Pa.
        neck_area: cross-section of the neck / opening, m^2.
        neck_length: length of the liquid column in the neck, m.
        wall_mass: mass of one wall patch, kg.
        c_wall: damping of the empty wall, N s/m.
        c_liq: extra damping per wall from the liquid's viscosity, N s/m.
        mass_empty: mass of the empty container, kg.
        spread: relative standard deviation of stiffness and compliance between instances.
        resealable: False for cans (they cannot be closed again once opened).
        squeeze_length: length of the zone that ovalises under the finger pads, m (the
            squeeze-volume model; an estimate: the pads' 3 cm plus the ~1 radius on either
            side over which a thin shell's ovalisation decays).
        grasp_spread: relative standard deviation of the shell stiffness from one grasp of
            the same instance to the next (log-normal; :func:`vary_grasp`; measured on the
            iCub grasps, see the module docstring).
    """

    name: str
    radius: float
    height: float
    volume: float
    k_wall: float
    area: float
    c_shell: float
    neck_area: float
    neck_length: float
    wall_mass: float
    c_wall: float
    c_liq: float
    mass_empty: float
    spread: float
    resealable: bool = True
    squeeze_length: float = 0.08
    grasp_spread: float = 0.0


#: The four container classes of Sec. 7.1.3 (Fig. 7.7a). Sizes are those of the products
#: (Odwalla 450 ml HDPE, Naked 450 ml PET, 355 ml aluminium can, 500 ml thin PET water
#: bottle); the stiffnesses are chosen so that a wall patch yields a few mm at 10-20 N as
#: squeezing such containers by hand does: the HDPE bottle thick-walled, the can stiff, the
#: water bottle flimsy and variable ("they tend to deform unpredictably").
CONTAINER_CLASSES = {
    "odwalla": ContainerClass("odwalla", radius=0.036, height=0.17, volume=0.45e-3,
                              k_wall=1800.0, area=1.6e-3, c_shell=2.0e-9, neck_area=4.5e-4,
                              neck_length=0.03, wall_mass=0.01, c_wall=4.0, c_liq=25.0,
                              mass_empty=0.045, spread=0.08, squeeze_length=0.10,
                              grasp_spread=ICUB_SPREAD_PLASTIC_BOTTLE),
    "naked": ContainerClass("naked", radius=0.030, height=0.18, volume=0.45e-3,
                            k_wall=1300.0, area=1.4e-3, c_shell=3.0e-9, neck_area=4.0e-4,
                            neck_length=0.03, wall_mass=0.008, c_wall=3.0, c_liq=20.0,
                            mass_empty=0.035, spread=0.15, squeeze_length=0.09,
                            grasp_spread=ICUB_SPREAD_PLASTIC_BOTTLE),
    "can": ContainerClass("can", radius=0.033, height=0.122, volume=0.355e-3,
                          k_wall=3000.0, area=1.2e-3, c_shell=1.2e-9, neck_area=3.0e-4,
                          neck_length=0.005, wall_mass=0.005, c_wall=3.0, c_liq=20.0,
                          mass_empty=0.015, spread=0.10, resealable=False,
                          squeeze_length=0.09, grasp_spread=ICUB_SPREAD_CAN),
    "water": ContainerClass("water", radius=0.0325, height=0.21, volume=0.5e-3,
                            k_wall=500.0, area=1.8e-3, c_shell=6.0e-9, neck_area=3.5e-4,
                            neck_length=0.03, wall_mass=0.004, c_wall=2.0, c_liq=20.0,
                            mass_empty=0.02, spread=0.35, squeeze_length=0.10,
                            grasp_spread=ICUB_SPREAD_PLASTIC_BOTTLE),
}


def states_of(name: str) -> tuple:
    """The internal states a container class can be in (cans: no ``empty_closed``)."""
    c = CONTAINER_CLASSES[name]
    return STATES if c.resealable else tuple(s for s in STATES if s != "empty_closed")


@dataclass(frozen=True)
class ContainerInstance:
    """One physical container in one state (all SI units; see the module docstring).

    Attributes:
        name, state: class and internal state (labels: never read by any sensor).
        radius, height: m.
        fill: liquid volume fraction (0 empty).
        k: total stiffness of each wall, N/m.
        c: total damping of each wall, N s/m.
        wall_mass: lumped mass of each wall incl. the liquid's added mass, kg.
        mass: total mass incl. liquid, kg.
        slosh_mass, slosh_k, slosh_c: the sloshing liquid (kg, N/m, N s/m; 0 when empty).
        k_parts: the contributions {"shell", "gas", "hydrostatic"} to ``k``, N/m.
        slosh_travel: the sloshing mass' travel, m (0: half the radius).
        closed: the cap is on (the squeeze-volume model's gas law applies).
        gas_volume: the enclosed gas (headspace; the whole volume when empty), m^3.
        shell_compliance: pressure compliance of the rest of the shell ``C_shell``, m^3/Pa.
        squeeze_length: length ``L`` of the ovalised zone, m.
        neck_area: cross-section of the neck, m^2.
        liquid_resistance: ``R_liq`` of a full container's volume flow, Pa s/m^3 (0 empty).
        c_wall: damping of the empty wall alone, N s/m (``c`` adds the liquid's).
        grasp_factor: this grasp's factor on the shell stiffness (:func:`vary_grasp`; 1: the
            instance as drawn), dimensionless.
    """

    name: str
    state: str
    radius: float
    height: float
    fill: float
    k: float
    c: float
    wall_mass: float
    mass: float
    slosh_mass: float
    slosh_k: float
    slosh_c: float
    k_parts: dict
    slosh_travel: float = 0.0
    closed: bool = False
    gas_volume: float = 0.0
    shell_compliance: float = 0.0
    squeeze_length: float = 0.0
    neck_area: float = 1.0
    liquid_resistance: float = 0.0
    c_wall: float = 0.0
    grasp_factor: float = 1.0

    def as_dict(self) -> dict:
        return asdict(self)


def sample_container(name: str, state: str, rng: np.random.Generator, *,
                     fill: float | None = None) -> ContainerInstance:
    """A random instance of class ``name`` in ``state`` (seeded through ``rng``).

    ``fill``: liquid volume fraction of a full state, in (0, 1) (default: drawn in 0.88-0.97;
    e.g. 0.5 for the half-full containers of the liquid-detection experiment)."""
    if fill is not None and not (np.isfinite(fill) and 0.0 < fill < 1.0):
        raise ValueError(f"fill: expected a volume fraction in (0, 1), got {fill!r}")
    if name not in CONTAINER_CLASSES:
        raise ValueError(f"container: unknown class {name!r}; choose from "
                         f"{', '.join(CONTAINER_CLASSES)}")
    if state not in states_of(name):
        raise ValueError(f"container {name!r}: unknown or impossible state {state!r}; choose "
                         f"from {', '.join(states_of(name))}")
    c = CONTAINER_CLASSES[name]
    full = state.startswith("full")
    closed = state.endswith("closed")

    def var(x, rel):
        return float(x * np.exp(rng.normal(0.0, rel)))

    radius = var(c.radius, 0.01)
    height = var(c.height, 0.01)
    k_wall = var(c.k_wall, c.spread)
    c_shell = var(c.c_shell, c.spread)
    area = var(c.area, 0.05)
    drawn = float(rng.uniform(0.88, 0.97)) if full else 0.0
    fill = (float(fill) if fill is not None else drawn) if full else 0.0
    v_liq = fill * c.volume
    k_gas = 0.0
    if closed:
        v_gas = c.volume - v_liq
        k_gas = 2.0 * area**2 / (v_gas / P0 + c_shell)
    k_hyd = 2.0 * area**2 * RHO_WATER * G / c.neck_area if (full and not closed) else 0.0
    m_add = RHO_WATER * c.neck_length * area**2 / c.neck_area if full else 0.0
    c_wall = var(c.c_wall, 0.1)
    c_liq = var(c.c_liq, 0.1) if full else 0.0
    damping = c_wall + c_liq
    # the ovalised length varies with the instance as the swept area does (the same geometry;
    # no extra draw, so the rng stream and every other draw stay as they were)
    squeeze_length = c.squeeze_length * area / c.area
    m_liq = RHO_WATER * v_liq
    # first sloshing mode of a liquid in a cylinder: omega^2 = g * 1.841 / R * tanh(...)
    if full:
        depth = v_liq / (np.pi * radius**2)
        w2 = G * 1.841 / radius * np.tanh(1.841 * depth / radius)
        ms = 0.4 * m_liq  # the sloshing share of the liquid (the rest moves rigidly)
        slosh_k, slosh_c = ms * w2, 2.0 * 0.05 * ms * np.sqrt(w2)
    else:
        ms, slosh_k, slosh_c = 0.0, 0.0, 0.0
    return ContainerInstance(
        name=name, state=state, radius=radius, height=height, fill=fill,
        k=k_wall + k_gas + k_hyd, c=damping, wall_mass=c.wall_mass + m_add,
        mass=c.mass_empty + m_liq, slosh_mass=float(ms), slosh_k=float(slosh_k),
        slosh_c=float(slosh_c),
        k_parts={"shell": k_wall, "gas": float(k_gas), "hydrostatic": float(k_hyd)},
        closed=bool(closed), gas_volume=float(c.volume - v_liq), shell_compliance=c_shell,
        squeeze_length=squeeze_length, neck_area=float(c.neck_area),
        liquid_resistance=float(c_liq / area**2), c_wall=c_wall)


def vary_grasp(inst: ContainerInstance, rng: np.random.Generator, *,
               mode: str = "wall") -> ContainerInstance:
    """The instance ``inst`` as one grasp meets it, with one factor
    ``m = exp(N(0, grasp_spread))`` drawn from ``rng`` per grasp (``grasp_spread`` of the
    instance's class, see the module docstring; recorded in ``grasp_factor``):

    * ``"wall"``: the wall's whole static response scales by ``m``: the shell stiffness
      (``k_parts["shell"]``, N/m) by ``m`` and the ovalised length ``squeeze_length`` by
      ``sqrt(m)``, so that the content's force ``dp * dV'`` (both proportional to the length
      at a given pinch) and the liquid's flow damping scale by ``m`` too (exactly for the head
      of an open bottle and the flow, to first order in ``dV / V_gas`` for the gas law); the
      linearised ``k`` and the liquid's share of ``c`` scale with them. The squeeze at a given
      force then varies by ``1 / m`` in every state, as the measured spread is one of the
      squeeze (the pads landing on a label, seam or rib, higher or lower, change both how stiff
      the shell is there and how much volume a pinch displaces);
    * ``"shell"``: only the shell stiffness scales by ``m`` (the content's coupling stays);
    * ``"none"``: ``inst`` unchanged, nothing drawn.

    The content (fill, gas volume, liquid) and the labels are untouched. ``inst`` must be as
    :func:`sample_container` drew it (``grasp_factor`` 1)."""
    if mode not in GRASP_VARIATIONS:
        raise ValueError(f"grasp_variation: expected one of {', '.join(GRASP_VARIATIONS)}, "
                         f"got {mode!r}")
    if not isinstance(inst, ContainerInstance):
        raise TypeError(f"vary_grasp: expected a ContainerInstance, got {type(inst).__name__}")
    if inst.grasp_factor != 1.0:
        raise ValueError(f"vary_grasp: the instance already carries a grasp factor "
                         f"({inst.grasp_factor:g}); vary the instance as drawn")
    if mode == "none":
        return inst
    if inst.name not in CONTAINER_CLASSES:
        raise ValueError(f"vary_grasp: unknown container class {inst.name!r}")
    sigma = CONTAINER_CLASSES[inst.name].grasp_spread
    m = float(np.exp(rng.normal(0.0, sigma)))
    if mode == "shell":
        shell = inst.k_parts["shell"]
        parts = dict(inst.k_parts, shell=float(shell * m))
        return replace(inst, k=float(inst.k + (m - 1.0) * shell), k_parts=parts,
                       grasp_factor=m)
    parts = {k: float(v * m) for k, v in inst.k_parts.items()}
    return replace(inst, k=float(inst.k * m), k_parts=parts,
                   c=float(inst.c_wall + (inst.c - inst.c_wall) * m),
                   squeeze_length=float(inst.squeeze_length * np.sqrt(m)), grasp_factor=m)


def _positive(name, x):
    x = float(x)
    if not (np.isfinite(x) and x > 0):
        raise ValueError(f"{name}: expected a finite number > 0, got {x!r}")
    return x


def squeeze_volume(d, *, squeeze_length: float):
    """Volume lost by a round container pinched by a total ``d`` (m, array; clipped at 0) and
    its derivative: ``(dV, dV')`` = ``(pi L d^2 / 4, pi L d / 2)`` in m^3 and m^2."""
    L = _positive("squeeze_length", squeeze_length)
    d = np.maximum(np.asarray(d, dtype=float), 0.0)
    return np.pi * L * d**2 / 4.0, np.pi * L * d / 2.0


def squeeze_pressure(d, *, closed: bool, full: bool, gas_volume: float,
                     shell_compliance: float, squeeze_length: float,
                     neck_area: float = 1.0, p0: float = P0):
    """Pressure rise of the content (Pa, array like ``d``) at a total pinch ``d`` (m).

    Closed: the isothermal gas law of the headspace ``gas_volume`` (m^3) at ``p0`` (Pa) with the
    rest of the shell bulging by ``shell_compliance * dp`` (m^3/Pa):
    ``C dp^2 + (V_g - dV + C p0) dp - p0 dV = 0``, the positive root (with ``C = 0`` this is
    ``p0 dV / (V_g - dV)``, Boyle's law). Open and full: the head
    ``rho g min(dV, V_g) / neck_area`` (``neck_area`` m^2; the liquid rises in the neck until
    it fills the headspace ``V_g`` and spills over the rim). Open and empty: 0."""
    dV, _ = squeeze_volume(d, squeeze_length=squeeze_length)
    return _pressure_rise(dV, closed=closed, full=full, gas_volume=gas_volume,
                          shell_compliance=shell_compliance, neck_area=neck_area, p0=p0)


def _pressure_rise(dV, *, closed, full, gas_volume, shell_compliance, neck_area, p0=P0):
    """:func:`squeeze_pressure` for a volume loss ``dV`` (m^3, array) already computed."""
    if closed:
        vg = _positive("gas_volume", gas_volume)
        C = float(shell_compliance)
        if not (np.isfinite(C) and C >= 0):
            raise ValueError(f"shell_compliance: expected a finite number >= 0, got {C!r}")
        b = vg - dV + C * p0
        # the positive root in the cancellation-free form 2c / (b + sqrt(b^2 + 4ac))
        disc = np.sqrt(b * b + 4.0 * C * p0 * dV)
        with np.errstate(divide="ignore", invalid="ignore"):
            dp = np.where(dV > 0, 2.0 * p0 * dV / (b + disc), 0.0)
        # C = 0 and the gas squeezed out entirely: Boyle's law has no finite answer
        return np.where(np.isfinite(dp) & (b + disc > 0), dp, np.inf)
    if full:
        # the liquid rises into the vented headspace (through the neck) and spills over the
        # rim once the headspace is full: the head stops growing there
        vg = _positive("gas_volume", gas_volume)
        return RHO_WATER * G * np.minimum(dV, vg) / _positive("neck_area", neck_area)
    return np.zeros_like(dV)


def wall_forces(inst: ContainerInstance, q, v):
    """Generalized forces (N, inward positive; shape of ``q``) of the content on the two walls
    at inward travels ``q = (..., 2)`` (m) and rates ``v`` (m/s): both walls feel
    ``-(dp(d) + R_liq Q) dV'(d)`` with ``d = q_l + q_r``, ``Q = dV'(d) (v_l + v_r)``. The
    shell's own linear spring and the empty wall's damping are not included."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    if q.shape[-1:] != (2,) or v.shape != q.shape:
        raise ValueError(f"wall_forces: expected q and v of shape (..., 2), got {q.shape} and "
                         f"{v.shape}")
    d = q[..., 0] + q[..., 1]
    full = inst.fill > 0
    dV, dVd = squeeze_volume(d, squeeze_length=inst.squeeze_length)
    dp = _pressure_rise(dV, closed=inst.closed, full=full, gas_volume=inst.gas_volume,
                        shell_compliance=inst.shell_compliance, neck_area=inst.neck_area)
    flow = inst.liquid_resistance * dVd * (v[..., 0] + v[..., 1]) if full else 0.0
    tau = -(dp + flow) * dVd
    return np.repeat(tau[..., None], 2, axis=-1)
