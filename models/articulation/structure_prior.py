"""A prior over kinematic structures that knows furniture (thesis Sec. 9.1's outlook).

The structure search (:mod:`mmlearn.models.articulation.graph`) scores a graph by its BIC
alone. When two fronts were only ever moved together, the data cannot tell "the second drawer
is fixed to the first, which slides in the carcass" from "both drawers slide in the carcass":
both explain the observations equally well, and the BIC prefers the first, which has fewer
parameters. Furniture is not built that way: fronts (doors, drawers, lids) hang on the
carcass, not on each other, and not on the floor.

:class:`StructurePrior` adds that knowledge as a term beside the BIC:

    score(G) = BIC(G) + sum over the edges (i, j) of c(role_i, role_j) log n,

with ``c = 0`` for a front on a carcass (or any edge between two fixed parts),
``c = front_front_params`` for a front on another front and ``c = front_floor_params`` for a
front on the floor; n is the number of time steps the BIC counts. An implausible edge thus
costs as much as that many extra parameters. The cost scales with log n like the BIC's own
penalty: in the ambiguous case the two explanations fit equally well and differ by a fixed
number of parameters (a coupled pair of prismatic links on the carcass has 5 more than a
prismatic link plus a rigid one), so a prior that did not grow with log n would lose to the
BIC's preference for fewer parameters as soon as n is large. A difference the data show grows
with n itself: a front that really moves on another front (a lid on a drawer) explains its
track through that front better by hundreds of BIC units, and the prior does not overturn it.

Roles (``"carcass"``, ``"front"``, ``"floor"``) are given by name or inferred from the
tracks (:func:`infer_roles`): a part that barely moves in the observation frame is fixed
(named like ``floor``/``ground``/``world`` it is the floor, else a carcass); the others are
fronts. If no part is fixed, the part that moves least is taken as the carcass.

The spanning tree the search starts from minimises the sum of the edges' link BIC plus their
prior cost (the MAP tree: both decompose over the edges), and the local search compares
graphs by ``score``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mmlearn.models.common.config import param, validate_fields

__all__ = ["ROLES", "StructurePrior", "infer_roles"]

ROLES = ("carcass", "front", "floor")
_FLOOR_NAMES = ("floor", "ground", "world")


def infer_roles(part_tracks, part_names, *, static_m: float = 0.02,
                static_rad: float = 0.05) -> dict:
    """Role of each part from its track (``(p, T, 7)`` poses, NaN rows unobserved): fixed
    when its positions stay within ``static_m`` of their median and its orientations within
    ``static_rad`` (95th percentile), else a front. Fixed parts named like floor / ground /
    world are the floor, the others carcasses; with no fixed part the least moving part is
    the carcass."""
    from mmlearn.models.articulation.graph import as_part_tracks

    Y = as_part_tracks(part_tracks)
    move = []
    for k in range(Y.shape[0]):
        y = Y[k][np.isfinite(Y[k]).all(axis=1)]
        if y.shape[0] < 2:
            move.append((math.inf, math.inf))
            continue
        dp = np.linalg.norm(y[:, :3] - np.median(y[:, :3], axis=0), axis=1)
        q = y[:, 3:] / np.linalg.norm(y[:, 3:], axis=1, keepdims=True)
        q0 = q[np.argmin(dp)]
        ang = 2 * np.arccos(np.clip(np.abs(q @ q0), 0.0, 1.0))
        move.append((float(np.percentile(dp, 95)), float(np.percentile(ang, 95))))
    roles = {}
    for name, (mp, ma) in zip(part_names, move):
        if mp <= static_m and ma <= static_rad:
            floor = any(w in str(name).lower() for w in _FLOOR_NAMES)
            roles[name] = "floor" if floor else "carcass"
        else:
            roles[name] = "front"
    if "carcass" not in roles.values() and "floor" not in roles.values():
        least = min(range(len(move)), key=lambda k: move[k][0] + move[k][1])
        roles[part_names[least]] = "carcass"
    return roles


@dataclass
class StructurePrior:
    """Mechanical plausibility of a kinematic structure (module docstring).

    Attributes:
        front_front_params: cost of a front hanging on another front, in parameters (the
            score adds this times log n).
        front_floor_params: cost of a front hanging on the floor, in parameters.
        roles: part name -> ``"carcass"``, ``"front"`` or ``"floor"``; parts not named are
            inferred (:func:`infer_roles`).
        static_m, static_rad: how little a fixed part moves (position, m; orientation, rad;
            95th percentile), for the inference.
    """

    front_front_params: float = param(8.0, ge=0)
    front_floor_params: float = param(8.0, ge=0)
    roles: dict = param(default_factory=dict)
    static_m: float = param(0.02, unit="m", gt=0)
    static_rad: float = param(0.05, unit="rad", gt=0)

    def validate(self) -> "StructurePrior":
        validate_fields(self)
        bad = {k: v for k, v in self.roles.items() if v not in ROLES}
        if bad:
            raise ValueError(f"StructurePrior.roles: unknown role(s) {bad}; choose from "
                             f"{', '.join(ROLES)}")
        return self

    def resolve_roles(self, part_tracks, part_names) -> dict:
        """Every part's role: the given ones, the rest inferred from the tracks."""
        self.validate()
        unknown = set(self.roles) - set(part_names)
        if unknown:
            raise ValueError(f"StructurePrior.roles names parts that are not observed: "
                             f"{sorted(unknown)} (parts: {list(part_names)})")
        inferred = infer_roles(part_tracks, part_names, static_m=self.static_m,
                               static_rad=self.static_rad)
        return {n: self.roles.get(n, inferred[n]) for n in part_names}

    def edge_params(self, role_a: str, role_b: str) -> float:
        """The cost of one edge between parts of these roles, in parameters."""
        pair = {role_a, role_b}
        if pair == {"front"}:
            return self.front_front_params
        if pair == {"front", "floor"}:
            return self.front_floor_params
        return 0.0

    def cost(self, edges, roles_by_index, n: int) -> float:
        """The prior's term of the score for a graph with ``edges`` ((i, j) index pairs)
        whose parts have the roles ``roles_by_index`` (list, by part index), ``n`` time
        steps, in BIC units."""
        if n < 2:
            raise ValueError(f"StructurePrior.cost: n must be >= 2 time steps, got {n}")
        return float(sum(self.edge_params(roles_by_index[i], roles_by_index[j])
                         for i, j in edges) * math.log(n))
