"""Imitation learning (thesis ch. 8): the shared data types of the teacher, the learner and the robot.

Plain numpy, no pydrake import. What the demonstration recorder produces
(:class:`Demonstration`), what :func:`mmlearn.models.imitation.dbn.learn_task` learns
(:class:`TaskModel`, the dynamic Bayesian network of Eq. 8.2 with one slice per time step) and
the obstacles the reproduction avoids (:class:`Obstacle`).

Conventions
-----------
* Positions are in the world frame, metres (LASA's 2-D handwriting data may use millimetres;
  the learner only needs consistent units). ``D`` is the Cartesian dimension: 3 for the arm,
  2 for LASA. Times are seconds.
* The *hand* is the gripper's tool centre point. Object names shared by the imitation code:
  ``"cup"``, ``"table_a"``, ``"table_b"``, ``"board_c0"`` .. ``"board_c3"`` (whiteboard
  corners, counter-clockwise from lower left), ``"obstacle"``, ``"target"``.
* **Gaps**: a row of ``hand`` or of an object track with any NaN entry means "marker not seen
  in that frame"; gaps are legal input (the learner interpolates them). Infinite values are
  never legal. A track that is NaN in every frame is an error.
* Constraint names in a :class:`TaskModel`: ``"obj:<name>"`` for the Cartesian constraint
  ``r_i = object_i - hand`` (Eq. 8.9), ``"joints"`` for the joint posture (Eq. 8.7) and
  ``"gripper"`` for the gripper opening (0 = closed .. 1 = open).

File formats (JSON, written atomically: temporary file + rename)
----------------------------------------------------------------
Demonstrations (:func:`save_demonstrations` / :func:`load_demonstrations`)::

    {"format": "mmlearn.demonstrations", "version": 2,   # 1: no checksum, still read
     "demonstrations": [
        {"t": [T floats, s],
         "hand": [[D floats, m] x T],            # null entries = NaN = marker unseen
         "objects": {"cup": [[D floats] x T], ...},
         "gripper": [T floats in 0..1] | null,
         "joints": [[n floats, rad] x T] | null,
         "meta": {...}},                           # any JSON object (task, seed, teacher, units)
        ...]}

Task model (:meth:`TaskModel.save` / :meth:`TaskModel.load`)::

    {"format": "mmlearn.task_model", "version": 2,       # 1: no checksum, still read
     "t": [S floats, s], "constraints": ["obj:cup", "gripper", ...],
     "mean": {"obj:cup": [[d floats] x S], ...},
     "var":  {"obj:cup": [[d floats] x S] (diagonal) or [[[d x d]] x S] (full), ...},
     "meta": {...}}
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mmlearn.models.common.fileio import atomic_write_text

__all__ = [
    "ImitationDataError",
    "Demonstration",
    "TaskModel",
    "Obstacle",
    "save_demonstrations",
    "load_demonstrations",
]

DEMO_FORMAT = "mmlearn.demonstrations"
MODEL_FORMAT = "mmlearn.task_model"
VERSION = 2
READABLE_VERSIONS = (1, 2)  # 1: before the checksum (last key "checksum": "sha256:<hex>",
#                              models/common/saved_doc.py): a truncated or edited file is an error


class ImitationDataError(ValueError):
    """Demonstrations, models or obstacles that cannot be used; the message names the field
    and the problem."""


# ---------------------------------------------------------------------------------------------
# helpers
def _as_float(name: str, a, *, ndim: int | None = None) -> np.ndarray:
    try:
        x = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise ImitationDataError(f"{name}: not a numeric array") from None
    if ndim is not None and x.ndim != ndim:
        raise ImitationDataError(f"{name}: expected {ndim} dimension(s), got shape {x.shape}")
    return x


def _check_track(name: str, a, T: int, *, ndim: int = 2, D: int | None = None,
                 allow_gaps: bool = True) -> np.ndarray:
    x = _as_float(name, a, ndim=ndim)
    if x.shape[0] != T:
        raise ImitationDataError(f"{name}: expected {T} samples (the length of t), got shape {x.shape}")
    if ndim == 2 and D is not None and x.shape[1] != D:
        raise ImitationDataError(f"{name}: expected {D} columns, got shape {x.shape}")
    if ndim == 2 and x.shape[1] == 0:
        raise ImitationDataError(f"{name}: zero columns")
    if np.isinf(x).any():
        bad = np.argwhere(np.isinf(x))[0]
        raise ImitationDataError(f"{name}: infinite value at index {tuple(int(i) for i in bad)}")
    nan = np.isnan(x)
    if nan.any():
        if not allow_gaps:
            bad = np.argwhere(nan)[0]
            raise ImitationDataError(f"{name}: NaN at index {tuple(int(i) for i in bad)}")
        rows = nan if ndim == 1 else nan.any(axis=1)
        if rows.all():
            raise ImitationDataError(f"{name}: NaN in every frame (never observed)")
    return x


def _nan_to_none(a: np.ndarray):
    """Nested lists with NaN replaced by None (JSON has no NaN)."""
    a = np.asarray(a, dtype=float)
    if not np.isnan(a).any():
        return a.tolist()
    o = a.astype(object)
    o[np.isnan(a)] = None
    return o.tolist()


def _from_json_array(name: str, v) -> np.ndarray:
    if v is None:
        raise ImitationDataError(f"{name}: missing")
    try:
        return np.array(v, dtype=float)  # None -> NaN
    except (TypeError, ValueError):
        raise ImitationDataError(f"{name}: not a (rectangular) numeric array") from None


def _json_meta(name: str, meta) -> dict:
    if not isinstance(meta, dict):
        raise ImitationDataError(f"{name}: meta must be a dict, got {type(meta).__name__}")
    try:
        json.dumps(meta, allow_nan=False)
    except (TypeError, ValueError) as e:
        raise ImitationDataError(f"{name}: meta is not JSON-serialisable ({e})") from None
    return meta


def _read_json(path, fmt: str) -> dict:
    from mmlearn.models.common.saved_doc import check_seal, read_document

    path = Path(path)
    if not path.is_file():
        raise ImitationDataError(f"{path}: file not found")
    try:
        doc = read_document(path, yaml_format=False)
    except ValueError as e:
        raise ImitationDataError(str(e)) from None
    if doc.get("format") != fmt:
        raise ImitationDataError(f"{path}: expected a JSON object with format {fmt!r}, "
                                 f"got {doc.get('format')!r}")
    version = doc.get("version")
    if isinstance(version, bool) or version not in READABLE_VERSIONS:
        raise ImitationDataError(f"{path}: unsupported version {version!r} (expected "
                                 f"{' or '.join(map(str, READABLE_VERSIONS))})")
    try:
        check_seal(doc, required=version >= 2)
    except ValueError as e:
        raise ImitationDataError(f"{path}: {e}") from None
    return doc


# ---------------------------------------------------------------------------------------------
@dataclass
class Demonstration:
    """One observed demonstration of a task.

    Attributes:
        t: ``(T,)`` sample times, s, strictly increasing (need not be uniform).
        hand: ``(T, D)`` hand (tool centre point) position in the world, m. A row with NaN =
            hand marker not seen in that frame.
        objects: object name -> ``(T, D)`` observed object marker position in the world, m
            (NaN rows = unseen).
        gripper: ``(T,)`` gripper opening, 0 = closed .. 1 = open (NaN = unknown), or None.
        joints: ``(T, n)`` joint angles of the teacher, rad (only when the teacher has the
            robot's kinematics; NaN rows = unknown), or None.
        meta: JSON-able dict (task, seed, teacher, units, ...).
    """

    t: np.ndarray
    hand: np.ndarray
    objects: dict[str, np.ndarray] = field(default_factory=dict)
    gripper: np.ndarray | None = None
    joints: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    @property
    def T(self) -> int:
        """Number of samples."""
        return int(np.asarray(self.t).shape[0])

    @property
    def D(self) -> int:
        """Cartesian dimension (2 or 3)."""
        return int(np.asarray(self.hand).shape[1])

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]``, s."""
        return float(self.t[-1] - self.t[0])

    def validate(self) -> "Demonstration":
        """Check shapes, finiteness and ordering; convert the arrays to float in place.

        Raises:
            ImitationDataError: naming the field and the problem (wrong shape, fewer than 2
                samples, t not strictly increasing, infinite values, a track NaN in every
                frame, gripper outside [0, 1], bad object name or meta).
        Returns:
            self (for chaining).
        """
        t = _as_float("t", self.t, ndim=1)
        if t.shape[0] < 2:
            raise ImitationDataError(f"t: a demonstration needs at least 2 samples, got {t.shape[0]}")
        if not np.all(np.isfinite(t)):
            raise ImitationDataError("t: NaN or infinite time stamp")
        if np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0))
            raise ImitationDataError(f"t: not strictly increasing at index {i + 1} ({t[i]:g} -> {t[i + 1]:g})")
        T = t.shape[0]
        hand = _check_track("hand", self.hand, T)
        D = hand.shape[1]
        if not isinstance(self.objects, dict):
            raise ImitationDataError(f"objects: expected a dict name -> (T, D) array, got {type(self.objects).__name__}")
        objects = {}
        for name, v in self.objects.items():
            if not isinstance(name, str) or not name or ":" in name:
                raise ImitationDataError(f"objects: bad object name {name!r} (a non-empty string without ':')")
            objects[name] = _check_track(f"objects[{name!r}]", v, T, D=D)
        gripper = None
        if self.gripper is not None:
            gripper = _check_track("gripper", self.gripper, T, ndim=1)
            g = gripper[np.isfinite(gripper)]
            if g.size and (g.min() < -1e-9 or g.max() > 1 + 1e-9):
                raise ImitationDataError(f"gripper: opening outside [0, 1] (min {g.min():g}, max {g.max():g})")
        joints = None
        if self.joints is not None:
            joints = _check_track("joints", self.joints, T)
        self.t, self.hand, self.objects, self.gripper, self.joints = t, hand, objects, gripper, joints
        self.meta = _json_meta("meta", self.meta)
        return self

    def to_dict(self) -> dict:
        """The JSON-able dict of the documented schema (NaN -> null)."""
        return {
            "t": np.asarray(self.t, dtype=float).tolist(),
            "hand": _nan_to_none(self.hand),
            "objects": {k: _nan_to_none(v) for k, v in self.objects.items()},
            "gripper": None if self.gripper is None else _nan_to_none(self.gripper),
            "joints": None if self.joints is None else _nan_to_none(self.joints),
            "meta": self.meta,
        }

    @classmethod
    def from_dict(cls, d: dict, *, where: str = "demonstration") -> "Demonstration":
        """Inverse of :meth:`to_dict`; validates. Errors are prefixed with ``where``."""
        if not isinstance(d, dict):
            raise ImitationDataError(f"{where}: expected a JSON object, got {type(d).__name__}")
        allowed = {"t", "hand", "objects", "gripper", "joints", "meta"}
        extra = set(d) - allowed
        if extra:
            raise ImitationDataError(f"{where}: unknown key(s) {sorted(extra)} (allowed: {sorted(allowed)})")
        try:
            objs = d.get("objects", {}) or {}
            if not isinstance(objs, dict):
                raise ImitationDataError("objects: expected a JSON object")
            demo = cls(
                t=_from_json_array("t", d.get("t")),
                hand=_from_json_array("hand", d.get("hand")),
                objects={k: _from_json_array(f"objects[{k!r}]", v) for k, v in objs.items()},
                gripper=None if d.get("gripper") is None else _from_json_array("gripper", d["gripper"]),
                joints=None if d.get("joints") is None else _from_json_array("joints", d["joints"]),
                meta=d.get("meta", {}) or {},
            )
            return demo.validate()
        except ImitationDataError as e:
            raise ImitationDataError(f"{where}: {e}") from None


def validate_demonstrations(demos) -> list[Demonstration]:
    """``demos`` as a list, each one a validated :class:`Demonstration`; raises
    ImitationDataError naming the first bad one and its problem."""
    demos = list(demos)
    for i, d in enumerate(demos):
        if not isinstance(d, Demonstration):
            raise ImitationDataError(f"demonstration {i}: expected a Demonstration, got {type(d).__name__}")
        try:
            d.validate()
        except ImitationDataError as e:
            raise ImitationDataError(f"demonstration {i}: {e}") from None
    return demos


def save_demonstrations(path, demos: list[Demonstration]) -> Path:
    """Validate and write ``demos`` to ``path`` as JSON (schema in the module docstring),
    atomically. Returns the path."""
    demos = validate_demonstrations(demos)
    from mmlearn.models.common.saved_doc import seal

    doc = seal({"format": DEMO_FORMAT, "version": VERSION,
                "demonstrations": [d.to_dict() for d in demos]})
    return atomic_write_text(path, json.dumps(doc, allow_nan=False))


def load_demonstrations(path) -> list[Demonstration]:
    """Read demonstrations written by :func:`save_demonstrations`; every one is validated.

    Raises:
        ImitationDataError: missing file, invalid JSON, wrong format/version, or a bad
            demonstration (the message names the file, its index and the field).
    """
    doc = _read_json(path, DEMO_FORMAT)
    lst = doc.get("demonstrations")
    if not isinstance(lst, list):
        raise ImitationDataError(f"{path}: 'demonstrations' must be a list")
    return [Demonstration.from_dict(d, where=f"{path}: demonstration {i}") for i, d in enumerate(lst)]


# ---------------------------------------------------------------------------------------------
@dataclass
class TaskModel:
    """The learned task: the DBN of Eq. 8.2 with one slice per time step ``t[k]``; every
    constraint is a Gaussian ``N(mean[name][k], var[name][k])`` per slice.

    Attributes:
        t: ``(S,)`` slice times, s, strictly increasing (starting at 0 for a learned model).
        constraints: constraint names (``"obj:<name>"``, ``"joints"``, ``"gripper"``).
        mean: name -> ``(S, d)`` mean (m for Cartesian constraints r_i = object_i - hand,
            rad for joints, 1 for the gripper opening).
        var: name -> ``(S, d)`` diagonal variances, or ``(S, d, d)`` full covariances
            (units squared).
        meta: JSON-able dict (h, dt, number of demonstrations, ...).
    """

    t: np.ndarray
    constraints: list[str]
    mean: dict[str, np.ndarray]
    var: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)

    @property
    def S(self) -> int:
        """Number of time slices."""
        return int(np.asarray(self.t).shape[0])

    @property
    def full_covariance(self) -> bool:
        """True when the variances are full ``(S, d, d)`` covariances."""
        return any(np.asarray(v).ndim == 3 for v in self.var.values())

    @property
    def objects(self) -> list[str]:
        """Names of the objects with a Cartesian constraint."""
        return [c[4:] for c in self.constraints if c.startswith("obj:")]

    def covariance(self, name: str, k: int) -> np.ndarray:
        """The ``(d, d)`` covariance of constraint ``name`` at slice ``k``."""
        v = np.asarray(self.var[name][k])
        return np.diag(v) if v.ndim == 1 else v

    def validate(self) -> "TaskModel":
        """Check shapes, finiteness and positivity; raises :class:`ImitationDataError`."""
        t = _as_float("t", self.t, ndim=1)
        if t.shape[0] < 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ImitationDataError("t: must be a non-empty, finite, strictly increasing (S,) array")
        S = t.shape[0]
        if not self.constraints:
            raise ImitationDataError("constraints: empty (nothing learned)")
        if len(set(self.constraints)) != len(self.constraints):
            raise ImitationDataError(f"constraints: duplicate names in {self.constraints}")
        for c in self.constraints:
            if not (c in ("joints", "gripper") or (c.startswith("obj:") and len(c) > 4)):
                raise ImitationDataError(f"constraints: bad name {c!r} (expected 'obj:<name>', 'joints' or 'gripper')")
        if set(self.mean) != set(self.constraints) or set(self.var) != set(self.constraints):
            raise ImitationDataError(
                f"mean/var keys {sorted(self.mean)}/{sorted(self.var)} differ from constraints {sorted(self.constraints)}")
        mean, var = {}, {}
        for c in self.constraints:
            m = _as_float(f"mean[{c!r}]", self.mean[c], ndim=2)
            if m.shape[0] != S:
                raise ImitationDataError(f"mean[{c!r}]: expected {S} slices, got shape {m.shape}")
            if not np.all(np.isfinite(m)):
                raise ImitationDataError(f"mean[{c!r}]: NaN or infinite value")
            v = _as_float(f"var[{c!r}]", self.var[c])
            d = m.shape[1]
            if v.shape not in ((S, d), (S, d, d)):
                raise ImitationDataError(f"var[{c!r}]: expected shape {(S, d)} or {(S, d, d)}, got {v.shape}")
            if not np.all(np.isfinite(v)):
                raise ImitationDataError(f"var[{c!r}]: NaN or infinite value")
            diag = v if v.ndim == 2 else np.diagonal(v, axis1=1, axis2=2)
            if np.any(diag <= 0):
                raise ImitationDataError(f"var[{c!r}]: variances must be positive (min {diag.min():g})")
            mean[c], var[c] = m, v
        self.t, self.mean, self.var = t, mean, var
        self.constraints = list(self.constraints)
        self.meta = _json_meta("meta", self.meta)
        return self

    def to_dict(self) -> dict:
        return {"format": MODEL_FORMAT, "version": VERSION, "t": np.asarray(self.t).tolist(),
                "constraints": list(self.constraints),
                "mean": {c: np.asarray(self.mean[c]).tolist() for c in self.constraints},
                "var": {c: np.asarray(self.var[c]).tolist() for c in self.constraints},
                "meta": self.meta}

    def save(self, path) -> Path:
        """Validate and write as JSON (schema in the module docstring), atomically."""
        self.validate()
        from mmlearn.models.common.saved_doc import seal

        return atomic_write_text(path, json.dumps(seal(self.to_dict()), allow_nan=False))

    @classmethod
    def load(cls, path) -> "TaskModel":
        """Read a model written by :meth:`save`; raises :class:`ImitationDataError` naming the
        file and the problem."""
        doc = _read_json(path, MODEL_FORMAT)
        try:
            extra = set(doc) - {"format", "version", "t", "constraints", "mean", "var", "meta",
                                "checksum"}
            if extra:
                raise ImitationDataError(f"unknown key(s) {sorted(extra)}")
            for k in ("mean", "var"):
                if not isinstance(doc.get(k), dict):
                    raise ImitationDataError(f"{k}: expected a JSON object")
            cons = doc.get("constraints")
            if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
                raise ImitationDataError("constraints: expected a list of strings")
            return cls(t=_from_json_array("t", doc.get("t")), constraints=cons,
                       mean={c: _from_json_array(f"mean[{c!r}]", v) for c, v in doc["mean"].items()},
                       var={c: _from_json_array(f"var[{c!r}]", v) for c, v in doc["var"].items()},
                       meta=doc.get("meta", {}) or {}).validate()
        except ImitationDataError as e:
            raise ImitationDataError(f"{path}: {e}") from None


# ---------------------------------------------------------------------------------------------
@dataclass
class Obstacle:
    """An oriented box obstacle in D = 2 or 3 dimensions.

    Attributes:
        centre: ``(D,)`` box centre in the world, m.
        half_size: ``(D,)`` half extents along the box axes, m (positive).
        R: ``(D, D)`` rotation from the box frame to the world (columns = box axes), or None
            for an axis-aligned box.
    """

    centre: np.ndarray
    half_size: np.ndarray
    R: np.ndarray | None = None

    def __post_init__(self):
        c = _as_float("Obstacle.centre", self.centre, ndim=1)
        h = _as_float("Obstacle.half_size", self.half_size, ndim=1)
        if c.shape != h.shape or c.shape[0] not in (2, 3):
            raise ImitationDataError(f"Obstacle: centre {c.shape} and half_size {h.shape} must both be (2,) or (3,)")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(h))) or np.any(h <= 0):
            raise ImitationDataError(f"Obstacle: centre must be finite and half_size positive, got {c}, {h}")
        R = None
        if self.R is not None:
            R = _as_float("Obstacle.R", self.R, ndim=2)
            D = c.shape[0]
            if R.shape != (D, D) or not np.allclose(R.T @ R, np.eye(D), atol=1e-6):
                raise ImitationDataError(f"Obstacle.R: expected a ({D}, {D}) rotation matrix")
        self.centre, self.half_size, self.R = c, h, R

    @property
    def D(self) -> int:
        return int(self.centre.shape[0])

    def _local(self, p) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        if p.shape[-1] != self.D:
            raise ImitationDataError(f"Obstacle: points of dimension {p.shape[-1]} for a {self.D}-D box")
        d = p - self.centre
        return d if self.R is None else d @ self.R

    def signed_distance(self, p) -> np.ndarray:
        """Signed distance from points ``p`` ``(..., D)`` (m) to the box surface, m: positive
        outside, negative inside. Returns shape ``p.shape[:-1]``."""
        q = np.abs(self._local(p)) - self.half_size
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
        inside = np.minimum(q.max(axis=-1), 0.0)
        return outside + inside

    def closest_point(self, p) -> np.ndarray:
        """The point of the box surface nearest to each of ``p`` ``(..., D)``, m (for a point
        inside, the nearest point on the face it is closest to)."""
        local = self._local(p)
        c = np.clip(local, -self.half_size, self.half_size)
        inside = np.all(np.abs(local) < self.half_size, axis=-1)
        if np.any(inside):
            gap = self.half_size - np.abs(local)            # distance to each face pair
            ax = np.argmin(gap, axis=-1)
            sgn = np.where(np.take_along_axis(local, ax[..., None], -1) >= 0, 1.0, -1.0)[..., 0]
            face = c.copy()
            np.put_along_axis(face, ax[..., None], (sgn * self.half_size[ax])[..., None], -1)
            c = np.where(inside[..., None], face, c)
        return self.centre + (c if self.R is None else c @ self.R.T)

    def to_dict(self) -> dict:
        return {"centre": self.centre.tolist(), "half_size": self.half_size.tolist(),
                "R": None if self.R is None else self.R.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "Obstacle":
        return cls(centre=d["centre"], half_size=d["half_size"], R=d.get("R"))
