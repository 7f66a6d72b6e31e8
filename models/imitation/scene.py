"""The imitation scene's layout (thesis ch. 8): tables, cup, board and obstacle as a spec.

Plain numpy: the teacher and the learner plan against this spec; :mod:`mmlearn.sdf.imitation`
builds the SDFormat scene from it.
"""

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from mmlearn.models.common.config import param, validate_fields

__all__ = ["ImitationSceneSpec", "SceneBox", "OBSTACLE_KINDS", "OBSERVED_BODIES", "ROBOT_TCP_IN_X8",
           "TEACHER_TCP_IN_X8", "TEACHER_OPENING", "stratified_table_shifts"]


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

    tables: bool = param(True)
    cup: bool = param(True)
    board: bool = param(False)
    target: bool = param(False)
    obstacle: str = param("none", choices=OBSTACLE_KINDS)
    table_a: list[float] = param([0.50, 0.32], unit="m", length=2, elements=True, factory=True)
    table_b: list[float] = param([0.50, -0.32], unit="m", length=2, elements=True, factory=True)
    table_size: list[float] = param([0.30, 0.30], unit="m", length=2, gt=0, factory=True)
    table_height: float = param(0.30, unit="m", gt=0)
    swap_tables: bool = param(False)
    cup_offset: list[float] = param([0.0, 0.0], unit="m", length=2, elements=True, factory=True)
    place_offset: list[float] = param([0.0, 0.0], unit="m", length=2, elements=True,
                                      factory=True)
    cup_radius: float = param(0.03, unit="m", gt=0)
    cup_height: float = param(0.10, unit="m", gt=0)
    cup_mass: float = param(0.15, unit="kg", gt=0)
    cup_modulus: float = param(1.0e6, unit="Pa", gt=0)
    board_centre: list[float] = param([0.65, 0.0, 0.65], unit="m", length=3, elements=True,
                                      factory=True)
    board_size: list[float] = param([0.70, 0.50], unit="m", length=2, gt=0, factory=True)
    board_area: list[float] = param([0.30, 0.20], unit="m", length=2, gt=0, factory=True)
    board_scale: float = param(1.0, gt=0)
    target_position: list[float] = param([0.55, -0.30, 0.30], unit="m", length=3,
                                         elements=True, factory=True)
    obstacle_centre: list[float] = param([0.50, 0.0, 0.40], unit="m", length=3, elements=True,
                                         factory=True)
    obstacle_size: list[float] = param([0.24, 0.05, 0.22], unit="m", length=3, gt=0,
                                       factory=True)
    u_inner_width: float = param(0.24, unit="m", gt=0)
    u_depth: float = param(0.18, unit="m", gt=0)
    u_height: float = param(0.45, unit="m", gt=0)
    u_thickness: float = param(0.03, unit="m", gt=0)
    seed: int | None = param(None, optional=True, integer=True)

    # ------------------------------------------------------------------ checks
    def validate(self) -> "ImitationSceneSpec":
        """Raise ValueError naming the first bad field; returns self."""
        validate_fields(self)
        half = np.asarray(self.table_size) / 2
        for k in ("cup_offset", "place_offset"):
            if np.any(np.abs(self.__dict__[k]) > half - self.cup_radius):
                raise ValueError(f"ImitationSceneSpec: {k} {self.__dict__[k]} puts the cup "
                                 f"off the table top (|{k}| must be <= table_size / 2 - "
                                 f"cup_radius, m)")
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
