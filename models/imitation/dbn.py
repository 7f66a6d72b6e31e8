"""Imitation learning (thesis ch. 8): learn a task as a DBN of Gaussian constraints and reproduce it.

Plain numpy/scipy/dtaidistance; no pydrake import. The kinematics of the robot enter only
through a Jacobian given by the caller, so the same code drives the 7-DOF Drake arm (D = 3)
and a 2-D point "hand" (J = identity, the LASA handwriting benchmark).

Learning (Sec. 8.1.1)
---------------------
:func:`align_demonstrations` fills marker gaps, resamples every demonstration onto a uniform
time base and warps it onto a reference demonstration by derivative dynamic time warping
(Keogh and Pazzani 2001; the DTW itself is ``dtaidistance``'s C implementation).
:func:`learn_task` then estimates, per time slice ``t_k`` of the aligned time base, a Parzen-
window (squared-exponential kernel, h = 0.2 s) weighted mean and covariance of every constraint
(Eq. 8.10-8.16):

* Cartesian constraints ``r_i = x_i - x_E`` (object minus hand; the thesis' Eq. 8.6-8.7), named
  ``"obj:<name>"``;
* the joint constraint ``r~ = q`` (Eq. 8.8-8.9), named ``"joints"`` (only when every
  demonstration has joint angles and ``use_joints``);
* the gripper opening, named ``"gripper"`` (not in the thesis' equations; learned the same way
  and read out as the gripper command).

Reproduction (Sec. 8.1.2)
-------------------------
:func:`constraint_step` is one incremental step (Eq. 8.17-8.24) with the corrections below;
:func:`reproduce_cartesian` iterates it for a point hand;
:func:`mmlearn.models.imitation.global_plan.plan_global` optimises the whole sequence on a
time-expanded roadmap with A* (Eq. 8.27-8.28, with the Eq. 8.28 cost's reading).

Corrections of the thesis text (checked by ``tests/test_imitation_model.py``)
-----------------------------------------------------------------------------
* **Eq. 8.18 sign.** With ``r_i = x_i - x_E`` the hand that satisfies constraint i is
  ``x_i - mu_i``, so the desired *hand* displacement is
  ``Delta_i = (x_i - x_E) - mu_i = x_i - mu_i - x_E``; the text's ``mu_i - (x_i - x_E)`` is the
  desired change of ``r_i``, i.e. the negative of the hand displacement, and drives the hand
  away from the target (``test_sign_single_constraint`` converges to ``x_i - mu_i``).
* **Eq. 8.19-8.20 transpose.** The damped least-squares map (Buss and Kim 2005) from a
  Cartesian displacement to a joint displacement is ``A = J^T (J J^T + lambda^2 I)^-1`` (n x D);
  the text's ``J (J J^T + lambda^2 I)^-1`` does not have matching dimensions for a D x n ``J``.
* **Eq. 8.20 rank.** ``A Sigma_i A^T`` has rank D < n and no inverse, so Eq. 8.23 cannot be
  evaluated as printed. We use its pseudo-inverse on the row space of ``J`` (zero precision in
  the null space of ``J``; numerically ``A^+T Sigma_i^-1 A^+`` with ``A^+ = V diag(1/a) U^T``
  from the SVD ``J = U diag(s) V^T``, ``a = s / (s^2 + lambda^2)``), and the pseudo-inverse of
  the summed precision. For a single Cartesian constraint this reproduces damped least squares
  exactly; for several constraints sharing ``J`` it is damped least squares applied to their
  precision-weighted combination (``test_sign_two_constraints``).
* **Eq. 8.23-8.24 product of Gaussians.** The fused step is
  ``q^ = q + Sigma^ (sum_c Sigma~_c^-1 Delta~_c)`` with
  ``Sigma^ = (sum_c Sigma~_c^-1)^-1`` (``Sigma^`` in Eq. 8.23, not ``Sigma~``). Eq. 8.24's
  ``Sigma^t`` inside the inverse adds a covariance to precisions (wrong units); read as the
  previous estimate's precision it would grow every step and freeze the arm, so it is left
  out: the damping ``lambda`` and the ``gain`` regularise the step instead.
* **Eq. 8.26 units.** ``exp(||x_O - x_E||^2)`` needs a length scale to be dimensionless:
  ``Sigma_O = beta * exp(||x_O - x_E||^2 / l^2) * I`` with ``l = obstacle_length`` (m; l = 1 m
  is the text). ``x_O`` is the closest point of the obstacle box to the hand.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple, Sequence

import numpy as np

from mmlearn.models.imitation.types import (Demonstration, ImitationDataError, Obstacle, TaskModel,
                                            validate_demonstrations)

__all__ = [
    "align_demonstrations",
    "learn_task",
    "StepResult",
    "constraint_step",
    "reproduce_cartesian",
    "fill_gaps",
    "resample",
    "derivative",
]


# =============================================================================================
# Alignment
def _interp_gaps(t: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Linear interpolation over time of the NaN rows of ``a`` ``(T,)`` or ``(T, d)``; leading and
    trailing gaps hold the nearest observed value."""
    a = np.asarray(a, dtype=float)
    one = a.ndim == 1
    x = a[:, None] if one else a
    bad = np.isnan(x).any(axis=1)
    if not bad.any():
        return a.copy()
    good = ~bad
    out = np.empty_like(x)
    for c in range(x.shape[1]):
        out[:, c] = np.interp(t, t[good], x[good, c])
    return out[:, 0] if one else out


def fill_gaps(demo: Demonstration) -> Demonstration:
    """A copy of ``demo`` with every NaN row (marker not seen) replaced by linear interpolation
    in time between the neighbouring observed frames; gaps at the start or end hold the first /
    last observed value. ``meta["gap_frames"]`` records how many hand frames were filled."""
    demo = Demonstration(t=demo.t, hand=demo.hand, objects=dict(demo.objects), gripper=demo.gripper,
                         joints=demo.joints, meta=dict(demo.meta)).validate()
    t = demo.t
    n_gap = int(np.isnan(demo.hand).any(axis=1).sum())
    return Demonstration(
        t=t.copy(), hand=_interp_gaps(t, demo.hand),
        objects={k: _interp_gaps(t, v) for k, v in demo.objects.items()},
        gripper=None if demo.gripper is None else _interp_gaps(t, demo.gripper),
        joints=None if demo.joints is None else _interp_gaps(t, demo.joints),
        meta={**demo.meta, "gap_frames": n_gap})


def resample(demo: Demonstration, t_new: np.ndarray) -> Demonstration:
    """Linear interpolation of a gap-free demonstration onto times ``t_new`` (s, within or
    clamped to the demonstration's time span)."""
    t = demo.t

    def f(a):
        if a is None:
            return None
        a = np.asarray(a, dtype=float)
        if a.ndim == 1:
            return np.interp(t_new, t, a)
        return np.stack([np.interp(t_new, t, a[:, c]) for c in range(a.shape[1])], axis=1)

    return Demonstration(t=np.asarray(t_new, dtype=float), hand=f(demo.hand),
                         objects={k: f(v) for k, v in demo.objects.items()},
                         gripper=f(demo.gripper), joints=f(demo.joints), meta=dict(demo.meta))


def derivative(x: np.ndarray) -> np.ndarray:
    """Keogh and Pazzani's (2001) derivative estimate for derivative DTW, per column of
    ``x`` ``(T, d)``: ``D[i] = ((x[i] - x[i-1]) + (x[i+1] - x[i-1]) / 2) / 2`` for interior
    points, the neighbour's estimate at both ends (units of x per sample)."""
    x = np.asarray(x, dtype=float)
    if x.shape[0] < 3:
        return np.zeros_like(x) if x.shape[0] < 2 else np.repeat(x[1:] - x[:1], 2, axis=0)
    d = np.empty_like(x)
    d[1:-1] = ((x[1:-1] - x[:-2]) + (x[2:] - x[:-2]) / 2.0) / 2.0
    d[0], d[-1] = d[1], d[-2]
    return d


def _features(demo: Demonstration) -> np.ndarray:
    """The series DTW compares: hand position and gripper opening (when present)."""
    cols = [demo.hand]
    if demo.gripper is not None:
        cols.append(demo.gripper[:, None])
    return np.concatenate(cols, axis=1)


def _check_demos(demos) -> list[Demonstration]:
    if isinstance(demos, Demonstration):
        demos = [demos]
    demos = list(demos)
    if not demos:
        raise ImitationDataError("no demonstrations given")
    demos = validate_demonstrations(demos)
    D = demos[0].D
    for i, d in enumerate(demos):
        if d.D != D:
            raise ImitationDataError(f"demonstration {i}: hand has {d.D} dimensions, demonstration 0 has {D}")
    return demos


def _check_period(dt, demos) -> None:
    """ImitationDataError unless ``dt`` (s) is None or a period shorter than every
    demonstration (a longer one leaves a single slice: a meaningless model)."""
    if dt is None:
        return
    if not (np.isfinite(dt) and dt > 0):
        raise ImitationDataError(f"dt must be a positive period in seconds, got {dt!r}")
    span = min(float(d.t[-1] - d.t[0]) for d in demos)
    if dt >= span:
        raise ImitationDataError(f"dt {dt:g} s is not shorter than the shortest demonstration "
                                 f"({span:g} s): the model would have a single slice")


def align_demonstrations(demos: Sequence[Demonstration], *, reference: int | None = None,
                         dt: float | None = None, window: float | None = None,
                         features: str = "both") -> list[Demonstration]:
    """Bring demonstrations onto one common time base by derivative dynamic time warping.

    Steps: (1) gaps (NaN rows) are filled by linear interpolation in time (:func:`fill_gaps`);
    (2) each demonstration is resampled at the uniform period ``dt``, with its time shifted to
    start at 0; (3) each is warped onto the reference: the DTW path (``dtaidistance``) between
    feature series of the hand and gripper maps every reference sample to one or more samples
    of the other demonstration, whose values are averaged. Objects present in only some
    demonstrations are dropped with a warning.

    Features (position columns scaled by their standard deviation, derivative columns by
    their root mean square over all demonstrations):
    ``"derivative"`` is the thesis' derivative DTW (Keogh and Pazzani's derivative estimate,
    :func:`derivative`); ``"position"`` plain DTW; ``"both"`` (default) the derivative and the
    position columns side by side. On simulated pick-and-place demonstrations with varied
    segment timing and placement, "both" aligns the phases best (the imitation page's
    deviations give the phase errors, made by ``benchmarks/bench_imitation.py``); on a smooth
    warp of one path, "position" aligns best and "derivative" worst. Derivatives scale with
    the local speed, which DTW cannot undo, so the derivative alone aligns speed changes
    poorly; positions alone are biased by object placements that differ between
    demonstrations; hence the default ``"both"``.

    Args:
        demos: the demonstrations (gaps, different lengths and durations are legal).
        reference: index of the reference demonstration (default: the one of median duration).
        dt: sample period of the common time base, s (default: the median sample period of all
            demonstrations, 0.2 s at the thesis' 5 Hz).
        window: optional Sakoe-Chiba band for DTW, s (None = unconstrained).
    Returns:
        The aligned demonstrations, all on the reference's time base ``k * dt``; a single
        demonstration is returned gap-filled and resampled (with a warning: nothing to align).
    Raises:
        ImitationDataError: empty input, bad demonstrations (named by index), different hand
            dimensions, bad ``reference``/``dt``.
    """
    if features not in ("derivative", "position", "both"):
        raise ImitationDataError(f"features must be 'derivative', 'position' or 'both', got {features!r}")
    demos = _check_demos(demos)
    _check_period(dt, demos)
    common = set(demos[0].objects)
    for d in demos[1:]:
        common &= set(d.objects)
    dropped = sorted(set().union(*[set(d.objects) for d in demos]) - common)
    if dropped:
        warnings.warn(f"align_demonstrations: objects {dropped} are not in every demonstration; dropped",
                      stacklevel=2)
    has_grip = all(d.gripper is not None for d in demos)
    n_joints = {None if d.joints is None else d.joints.shape[1] for d in demos}
    has_joints = None not in n_joints and len(n_joints) == 1
    filled = []
    for d in demos:
        f = fill_gaps(d)
        f.objects = {k: v for k, v in f.objects.items() if k in common}
        if not has_grip:
            f.gripper = None
        if not has_joints:
            f.joints = None
        filled.append(f)
    if dt is None:
        dt = float(np.median(np.concatenate([np.diff(d.t) for d in filled])))
    if not (np.isfinite(dt) and dt > 0):
        raise ImitationDataError(f"dt must be a positive period in seconds, got {dt!r}")
    res = []
    for f in filled:
        n = int(np.floor(f.duration / dt + 1e-9)) + 1
        r = resample(f, f.t[0] + dt * np.arange(max(n, 2)))
        r.t = r.t - r.t[0]
        res.append(r)
    if reference is None:
        durs = np.array([r.duration for r in res])
        reference = int(np.argsort(durs)[(len(durs) - 1) // 2])
    if not (0 <= int(reference) < len(res)):
        raise ImitationDataError(f"reference {reference} is not a demonstration index (0..{len(res) - 1})")
    reference = int(reference)
    if len(res) == 1:
        warnings.warn("align_demonstrations: a single demonstration, nothing to align", stacklevel=2)
        return res
    from dtaidistance import dtw_ndim

    feats = [_features(r) for r in res]
    pscale = np.concatenate(feats).std(axis=0)
    dscale = np.sqrt(np.mean(np.concatenate([derivative(f) for f in feats]) ** 2, axis=0))  # RMS: not centred
    pscale[pscale < 1e-12] = 1.0
    dscale[dscale < 1e-12] = 1.0

    def fe(f):
        d = derivative(f) / dscale
        x = d if features == "derivative" else (f / pscale if features == "position"
                                                else np.concatenate([d, f / pscale], axis=1))
        return np.ascontiguousarray(x, dtype=np.double)

    dfeats = [fe(f) for f in feats]
    ref = res[reference]
    Tr = ref.T
    out = []
    kw = {} if window is None else {"window": max(1, int(round(window / dt)))}
    for g, r in enumerate(res):
        if g == reference:
            out.append(Demonstration(t=ref.t.copy(), hand=ref.hand, objects=dict(ref.objects),
                                     gripper=ref.gripper, joints=ref.joints,
                                     meta={**ref.meta, "aligned_to": reference}))
            continue
        path = np.asarray(dtw_ndim.warping_path(dfeats[reference], dfeats[g], use_c=True, **kw))
        # every reference index i gets the mean of the matched samples j
        cnt = np.bincount(path[:, 0], minlength=Tr).astype(float)

        def warp(a):
            if a is None:
                return None
            a = np.asarray(a, dtype=float)
            a2 = a[:, None] if a.ndim == 1 else a
            acc = np.zeros((Tr, a2.shape[1]))
            np.add.at(acc, path[:, 0], a2[path[:, 1]])
            acc /= cnt[:, None]
            return acc[:, 0] if a.ndim == 1 else acc

        out.append(Demonstration(t=ref.t.copy(), hand=warp(r.hand),
                                 objects={k: warp(v) for k, v in r.objects.items()},
                                 gripper=warp(r.gripper), joints=warp(r.joints),
                                 meta={**r.meta, "aligned_to": reference}))
    return out


# =============================================================================================
# Learning (Eq. 8.10-8.16)
def parzen_weights(t_slices: np.ndarray, t_samples: np.ndarray, *, h: float, G: int) -> np.ndarray:
    """Eq. 8.10-8.12: the weight of a sample at time ``t'`` for slice ``t``,
    ``w = K((t' - t) / h) / eta_t`` with the squared-exponential kernel ``K(d) = exp(-d^2 / 2)``
    (Eq. 8.11) and ``eta_t`` normalising the weights of all ``G`` demonstrations' samples for
    slice ``t`` to one (Eq. 8.12). Returns ``(S, T)``: the weight of each of the G
    demonstrations' sample ``t'`` (identical across demonstrations on the aligned time base)."""
    d = (np.asarray(t_samples)[None, :] - np.asarray(t_slices)[:, None]) / h
    K = np.exp(-0.5 * d * d)
    return K / (G * K.sum(axis=1, keepdims=True))


def _pool_isotropic(v: np.ndarray, nu: float, G: int) -> np.ndarray:
    """Posterior mean covariance under an isotropic conjugate prior of ``nu`` pseudo
    demonstrations (see :func:`learn_task`): ``v`` (S, D) variances or (S, D, D)
    covariances of ``G`` demonstrations."""
    D = v.shape[1]
    if v.ndim == 2:
        iso = np.repeat(v.mean(axis=1, keepdims=True), D, axis=1)
    else:
        iso = (np.trace(v, axis1=1, axis2=2) / D)[:, None, None] * np.eye(D)
    return (nu * iso + G * v) / (nu + G)


def learn_task(demos: Sequence[Demonstration], *, h: float = 0.2, dt: float | None = None,
               use_joints: bool = True, full_covariance: bool = False, min_var: float = 1e-6,
               reference: int | None = None, align: bool = True,
               align_features: str = "both", isotropic_prior: float = 0.0) -> TaskModel:
    """Learn the task model (the DBN of Eq. 8.2, one slice per aligned sample) from demonstrations.

    For each slice ``t_k`` and constraint ``c`` with per-sample value ``v^{g}(t')`` (object minus
    hand for ``"obj:<name>"``, joint angles for ``"joints"``, gripper opening for ``"gripper"``):
    the weighted mean ``mu_k = sum_{g,t'} w_k(t') v^g(t')`` (Eq. 8.13, 8.15) and the weighted,
    bias-corrected covariance ``Sigma_k = sum w (v - mu)(v - mu)^T / (1 - sum w^2)``
    (Eq. 8.14, 8.16); diagonal by default (the thesis' experiments, Sec. 8.2), full with
    ``full_covariance``. Variances are floored at ``min_var`` (full: ``min_var * I`` is added).

    Args:
        demos: demonstrations (aligned by :func:`align_demonstrations` unless ``align=False``,
            in which case they must already share one time base).
        h: Parzen window width, s (the thesis: 0.2 s).
        dt: period of the slices, s (default: the demonstrations' median sample period).
        use_joints: learn the joint constraint when every demonstration has joint angles.
        full_covariance: full ``(d, d)`` covariances instead of diagonal variances.
        min_var: variance floor, in the constraint's units squared (m^2, rad^2, 1).
        reference: reference demonstration for the alignment (see :func:`align_demonstrations`).
        align: align first (True) or use the demonstrations' common time base as is.
        align_features: DTW features, see :func:`align_demonstrations`.
        isotropic_prior: strength, in demonstrations, of a prior that an object's relation
            to the hand spreads alike in every direction (0 = none, the thesis). Each
            Cartesian constraint's covariance becomes the posterior mean
            ``(nu * (tr(Sigma) / D) * I + G * Sigma) / (nu + G)`` (G demonstrations, ``nu =
            isotropic_prior``), a conjugate (inverse-Wishart) prior centred on the
            constraint's own mean variance. Relevance is a property of the object: from
            two or three demonstrations an irrelevant object's relation often varies little
            along one axis by chance (the tables moved alike along x), and the unpooled
            variance then makes it steer that axis; the prior stops that, and its weight
            fades as demonstrations accumulate. Joint and gripper constraints are left as
            they are.
    Returns:
        The :class:`TaskModel` with ``t = k * dt`` and ``meta`` holding h, dt, the number of
        demonstrations, the dimension D, the reference index and ``isotropic_prior``.
    """
    if not (np.isfinite(h) and h > 0):
        raise ImitationDataError(f"h must be a positive window width in seconds, got {h!r}")
    if not (np.isfinite(min_var) and min_var > 0):
        raise ImitationDataError(f"min_var must be positive, got {min_var!r}")
    if not (np.isfinite(isotropic_prior) and isotropic_prior >= 0):
        raise ImitationDataError(f"isotropic_prior must be a finite number >= 0 "
                                 f"(demonstrations), got {isotropic_prior!r}")
    demos = _check_demos(demos)
    _check_period(dt, demos)
    if align:
        with warnings.catch_warnings():
            if len(demos) == 1:
                warnings.simplefilter("ignore")
            al = align_demonstrations(demos, reference=reference, dt=dt, features=align_features)
        if len(demos) == 1:
            warnings.warn("learn_task: a single demonstration gives only the Parzen-window spread "
                          "(plus min_var) as variance: the model cannot tell relevant from "
                          "irrelevant constraints", stacklevel=2)
    else:
        al = [fill_gaps(d) for d in demos]
        for i, d in enumerate(al):
            if d.T != al[0].T or not np.allclose(d.t - d.t[0], al[0].t - al[0].t[0]):
                raise ImitationDataError(f"align=False: demonstration {i} is not on demonstration 0's time base")
    G = len(al)
    if use_joints:
        nj = {None if d.joints is None else d.joints.shape[1] for d in al}
        if len(nj) > 1:
            warnings.warn(f"learn_task: joint angles missing or of different sizes {sorted(map(str, nj))} "
                          "across the demonstrations; no joint constraint learned", stacklevel=2)
    t = al[0].t - al[0].t[0]
    W = parzen_weights(t, t, h=h, G=G)                       # (S, T), sums over g and t' to 1
    denom = 1.0 - G * np.sum(W * W, axis=1)                   # Eq. 8.14's 1 - sum w^2
    denom = np.maximum(denom, 1e-12)

    series: dict[str, np.ndarray] = {}
    for name in al[0].objects:
        series[f"obj:{name}"] = np.stack([d.objects[name] - d.hand for d in al])     # (G, T, D)
    if use_joints and all(d.joints is not None for d in al):
        series["joints"] = np.stack([d.joints for d in al])
    if all(d.gripper is not None for d in al):
        series["gripper"] = np.stack([d.gripper[:, None] for d in al])
    if not series:
        raise ImitationDataError("no constraint to learn: the demonstrations have no objects, joints or gripper")
    mean, var = {}, {}
    for c, v in series.items():
        # weighted moments; sum_{g,t'} w = 1, so sum w (v - mu)(v - mu)^T = sum w v v^T - mu mu^T.
        # The values are centred on their overall mean first, which keeps the subtraction exact
        # to ~1e-16 of the data's spread (float64), and the memory at O(S T) instead of O(G S T d).
        c0 = v.reshape(-1, v.shape[2]).mean(axis=0)
        vc = v - c0
        m1 = np.einsum("st,gtd->sd", W, vc)                              # Eq. 8.13 / 8.15
        if full_covariance:
            m2 = np.einsum("st,gtd,gte->sde", W, vc, vc)
            cov = (m2 - m1[:, :, None] * m1[:, None, :]) / denom[:, None, None]     # Eq. 8.14 / 8.16
            cov = 0.5 * (cov + np.swapaxes(cov, 1, 2)) + min_var * np.eye(v.shape[2])
            var[c] = cov
        else:
            m2 = np.einsum("st,gtd->sd", W, vc * vc)
            var[c] = np.maximum((m2 - m1 * m1) / denom[:, None], min_var)
        if isotropic_prior > 0 and c.startswith("obj:"):
            var[c] = _pool_isotropic(var[c], isotropic_prior, G)
        mean[c] = m1 + c0
    meta = {"h": float(h), "dt": float(t[1] - t[0]) if len(t) > 1 else None, "n_demos": G,
            "D": al[0].D, "reference": al[0].meta.get("aligned_to"), "full_covariance": bool(full_covariance),
            "min_var": float(min_var), "isotropic_prior": float(isotropic_prior)}
    return TaskModel(t=t, constraints=list(series), mean=mean, var=var, meta=meta).validate()


# =============================================================================================
# Incremental reproduction (Eq. 8.17-8.26)
class StepResult(NamedTuple):
    """Result of one incremental step.

    Attributes:
        dq: ``(n,)`` joint displacement to apply, rad (or m for a point hand).
        target_hand: ``(D,)`` the precision-weighted combination of the Cartesian constraints'
            hand targets ``x_i - mu_i`` (m), or None when no Cartesian constraint was active.
        info: dict with ``"cov"`` (n x n fused covariance Sigma^ of Eq. 8.24, corrected),
            ``"targets"`` (name -> hand target), ``"skipped"`` (constraints without a valid
            observation this step), ``"gripper"`` (learned opening at slice k, or None),
            ``"clearance"`` (min signed distance hand - obstacles, m, or None), ``"k"``.
    """

    dq: np.ndarray
    target_hand: np.ndarray | None
    info: dict

    @property
    def gripper(self):
        """The learned gripper opening at this slice (0 closed .. 1 open), or None."""
        return self.info.get("gripper")


def _dls_information(J: np.ndarray, Sigma_inv: np.ndarray, delta: np.ndarray, damping: float,
                     svd=None):
    """Joint-space precision and information vector of a Cartesian Gaussian constraint mapped
    by damped least squares (Eq. 8.19-8.20, corrected: see the module docstring).

    Returns ``(Lambda (n, n), eta (n,))`` with ``Lambda = A^{+T} Sigma^-1 A^+`` and
    ``eta = A^{+T} Sigma^-1 delta`` where ``A^+ = V diag(1/a) U^T``, ``a = s / (s^2 + l^2)``."""
    U, s, Vt = svd if svd is not None else np.linalg.svd(J, full_matrices=False)
    s_eff = np.maximum(s, 1e-6)
    inv_a = (s_eff ** 2 + damping ** 2) / s_eff                        # 1 / a
    B = (Vt.T * inv_a) @ U.T                                           # (n, D) = A^{+T}
    return B @ Sigma_inv @ B.T, B @ (Sigma_inv @ delta)


def _obstacle_constraints(p, obstacles, *, alpha, beta, length):
    """Eq. 8.25-8.26 for a point ``p``: for each obstacle, the displacement ``alpha`` away from
    its closest point and the isotropic covariance ``beta * exp(d^2 / l^2)``. Yields
    ``(delta, var, signed_distance)``."""
    for ob in obstacles:
        sd = float(ob.signed_distance(p))
        xo = ob.closest_point(p)
        v = p - xo
        nv = np.linalg.norm(v)
        if nv < 1e-12:                       # on the surface: push along centre -> point
            v = p - ob.centre
            nv = max(np.linalg.norm(v), 1e-12)
        away = v / nv if sd >= 0 else -v / nv
        var = beta * np.exp(min((sd / length) ** 2, 600.0)) if sd > 0 else beta
        yield alpha * away, var, sd


def constraint_step(model: TaskModel, k: int, *, hand, objects: dict, J, q=None, gripper=None,
                    use_joints: bool = True, damping: float = 0.05, gain: float = 1.0,
                    obstacles: Sequence[Obstacle] = (), obstacle_alpha: float = 0.05,
                    obstacle_beta: float = 1e-8, obstacle_length: float = 0.05,
                    obstacle_points: Sequence[tuple] = (), use_objects: Sequence[str] | None = None,
                    carried: Sequence[str] = (), max_step: float | None = None) -> StepResult:
    """One incremental reproduction step towards slice ``k`` (the thesis' ``t+1``), Eq. 8.17-8.24.

    Each Cartesian constraint i whose object is observed gives the hand displacement
    ``Delta_i = x_i - mu_i^k - x_E`` (Eq. 8.18, sign corrected) with covariance ``Sigma_i^k``,
    mapped to joint space by damped least squares (Eq. 8.19-8.20, corrected); the joint
    constraint gives ``mu~^k - q`` with ``Sigma~^k`` (Eq. 8.21-8.22); each obstacle adds the
    attractor of Eq. 8.25-8.26 for the hand and for every extra ``obstacle_points`` entry; all
    are fused as a product of Gaussians (Eq. 8.23-8.24, corrected) and
    ``dq = gain * (q^ - q)``.

    Args:
        model: the learned :class:`TaskModel`.
        k: target slice index, 0 <= k < model.S.
        hand: ``(D,)`` current hand (tool centre point) position, m.
        objects: name -> ``(D,)`` current observed object position, m. A missing or non-finite
            entry skips that constraint this step (documented fallback, listed in
            ``info["skipped"]``).
        J: ``(D, n)`` hand Jacobian d hand / d q (m/rad; the identity for a point hand).
        q: ``(n,)`` current joint angles, rad (needed for the joint constraint).
        gripper: current gripper opening (unused by the fusion; recorded in info).
        use_joints: use the learned joint constraint (off for a body with other kinematics).
        damping: damped-least-squares lambda, in the units of J (m for an arm, 1 for J = I).
        gain: fraction of the fused displacement applied, 0 < gain <= 1.
        obstacles: :class:`Obstacle` boxes (same D as the hand).
        obstacle_alpha: Eq. 8.25's alpha: length of the attractor displacement, m.
        obstacle_beta: Eq. 8.26's beta: attractor variance at contact, m^2 (smaller = stronger).
        obstacle_length: length scale l of Eq. 8.26, m.
        obstacle_points: extra ``(point (D,), jacobian (D, n))`` pairs on the robot (e.g. the
            elbow, a carried object) that also get obstacle attractors.
        use_objects: restrict the Cartesian constraints to these object names (default: all).
        carried: object names held in the hand: their constraint is skipped (it moves with the
            hand and is satisfied by construction).
        max_step: largest joint step ``|dq|`` (Euclidean norm, rad or m), None = unlimited: a
            longer step is scaled down (a speed limit; keeps an obstacle from being jumped over).
    Returns:
        :class:`StepResult`.
    Raises:
        ValueError (ImitationDataError): non-finite hand/J/q, wrong shapes, k out of range,
            joint constraint requested without ``q``.
    """
    S = model.S
    if not (0 <= int(k) < S):
        raise ImitationDataError(f"k={k} outside the model's slices 0..{S - 1}")
    k = int(k)
    hand = np.asarray(hand, dtype=float)
    D = int(model.meta.get("D", hand.shape[0])) if model.meta.get("D") is not None else hand.shape[0]
    if hand.shape != (D,) or not np.all(np.isfinite(hand)):
        raise ImitationDataError(f"hand must be a finite ({D},) position, got {hand!r}")
    J = np.asarray(J, dtype=float)
    if J.ndim != 2 or J.shape[0] != D or not np.all(np.isfinite(J)):
        raise ImitationDataError(f"J must be a finite ({D}, n) Jacobian, got shape {J.shape}")
    n = J.shape[1]
    if not (0 < gain <= 1) or not (damping >= 0):
        raise ImitationDataError(f"gain must be in (0, 1] and damping >= 0, got {gain!r}, {damping!r}")
    if q is not None:
        q = np.asarray(q, dtype=float)
        if q.shape != (n,) or not np.all(np.isfinite(q)):
            raise ImitationDataError(f"q must be a finite ({n},) vector matching J, got {q!r}")
    svd = np.linalg.svd(J, full_matrices=False)
    Lam = np.zeros((n, n))
    eta = np.zeros(n)
    targets, skipped = {}, []
    P_sum = np.zeros((D, D))
    Pt_sum = np.zeros(D)
    names = model.objects if use_objects is None else [o for o in model.objects if o in set(use_objects)]
    for name in names:
        c = f"obj:{name}"
        x = objects.get(name) if isinstance(objects, dict) else None
        x = None if x is None else np.asarray(x, dtype=float)
        if name in carried or x is None or x.shape != (D,) or not np.all(np.isfinite(x)):
            skipped.append(c)
            continue
        mu = model.mean[c][k]
        Sig = model.covariance(c, k)
        P = np.linalg.inv(Sig)
        target = x - mu                                    # hand that satisfies r_i = mu_i
        targets[name] = target
        P_sum += P
        Pt_sum += P @ target
        L, e = _dls_information(J, P, target - hand, damping, svd)   # Delta_i: Eq. 8.18 corrected
        Lam += L
        eta += e
    if use_joints and "joints" in model.constraints:
        if q is None:
            raise ImitationDataError("the model has a joint constraint: pass q or use_joints=False")
        if model.mean["joints"].shape[1] != n:
            raise ImitationDataError(f"joint constraint has {model.mean['joints'].shape[1]} joints, J has {n} columns")
        Pj = np.linalg.inv(model.covariance("joints", k))
        Lam += Pj                                          # Eq. 8.22
        eta += Pj @ (model.mean["joints"][k] - q)          # Eq. 8.21
    clearance = None
    if obstacles:
        pts = [(hand, J, svd)] + [(np.asarray(p, float), np.asarray(Jp, float), None) for p, Jp in obstacle_points]
        for p, Jp, sv in pts:
            for delta, var, sd in _obstacle_constraints(p, obstacles, alpha=obstacle_alpha,
                                                        beta=obstacle_beta, length=obstacle_length):
                clearance = sd if clearance is None else min(clearance, sd)
                L, e = _dls_information(Jp, np.eye(D) / var, delta, damping, sv)
                Lam += L
                eta += e
    if np.any(Lam):
        cov = np.linalg.pinv(Lam, hermitian=True)          # Eq. 8.24 (corrected)
        dq = gain * (cov @ eta)                            # Eq. 8.23 (corrected)
        if max_step is not None:
            nd = float(np.linalg.norm(dq))
            if nd > max_step:
                dq *= max_step / nd
    else:
        cov = np.full((n, n), np.inf)
        dq = np.zeros(n)
    target_hand = np.linalg.solve(P_sum, Pt_sum) if targets else None
    g = None
    if "gripper" in model.constraints:
        g = float(np.clip(model.mean["gripper"][k, 0], 0.0, 1.0))
    info = {"cov": cov, "targets": targets, "skipped": skipped, "gripper": g, "clearance": clearance,
            "k": k, "gripper_observed": gripper}
    return StepResult(dq=dq, target_hand=target_hand, info=info)


def _slice_of_time(model: TaskModel, s: float) -> int:
    return int(np.clip(np.searchsorted(model.t, s - 1e-9), 0, model.S - 1))


def reproduce_cartesian(model: TaskModel, x0, objects: dict, *, duration: float | None = None,
                        dt: float | None = None, damping: float = 0.0, gain: float = 1.0,
                        obstacles: Sequence[Obstacle] = (), substeps: int = 1,
                        extra_time: float = 0.0, **step_kwargs) -> tuple[np.ndarray, np.ndarray]:
    """Incremental reproduction with a point hand (``J = I``, the hand position is the
    "configuration"): from ``x0``, every period ``dt`` one :func:`constraint_step` towards the
    next slice (``substeps`` steps per period, e.g. to let the obstacle attractor act more
    often).

    Args:
        model: the learned task (Cartesian constraints; joint constraints are ignored).
        x0: ``(D,)`` start position of the hand (m, or the data's unit).
        objects: name -> ``(D,)`` static object positions.
        duration: reproduction length, s (default: the model's duration); the model's time is
            scaled by ``model_duration / duration`` when they differ.
        dt: output period, s (default: the model's slice period).
        damping, gain, obstacles, step_kwargs: passed to :func:`constraint_step`.
        extra_time: seconds appended after ``duration`` that keep stepping towards the last
            slice (e.g. to finish after a detour around an obstacle).
    Returns:
        ``(t (N,), x (N, D))`` with ``t[0] = 0`` and ``x[0] = x0``.
    """
    x = np.asarray(x0, dtype=float).copy()
    D = x.shape[0]
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        raise ImitationDataError(f"x0 must be a finite (D,) position, got {x0!r}")
    T_model = float(model.t[-1])
    if dt is None:
        dt = float(model.meta.get("dt") or (model.t[1] - model.t[0] if model.S > 1 else 0.1))
    if duration is None:
        duration = T_model
    if not (dt > 0 and duration >= 0):
        raise ImitationDataError(f"dt must be > 0 and duration >= 0, got {dt!r}, {duration!r}")
    n_steps = int(round(duration / dt))
    n_total = n_steps + int(round(max(extra_time, 0.0) / dt))
    scale = T_model / duration if duration > 0 else 1.0
    I = np.eye(D)
    ts = [0.0]
    xs = [x.copy()]
    for s in range(1, n_total + 1):
        k = _slice_of_time(model, min(s, n_steps) * dt * scale)
        for _ in range(max(1, substeps)):
            r = constraint_step(model, k, hand=x, objects=objects, J=I, q=x, use_joints=False,
                                damping=damping, gain=gain, obstacles=obstacles, **step_kwargs)
            x = x + r.dq
        ts.append(s * dt)
        xs.append(x.copy())
    return np.array(ts), np.array(xs)
