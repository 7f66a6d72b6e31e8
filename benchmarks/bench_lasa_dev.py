"""LASA development study (issue 15, lasa3): where the thesis' reproduction errs, and how the
settings of :class:`mmlearn.models.imitation.lasa.ThesisReproducer` move the leave-one-out rmse, **on the
9 development shapes only** (``DEVELOPMENT_SHAPES``; the held-back shapes are never read here).

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lasa_dev.py split
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lasa_dev.py extras
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lasa_dev.py condition [--only "NAME;..."]
        [--variant 'LABEL={"condition": ["target"], "ridge": 1, ...}' ...] [--out FILE.jsonl]
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lasa_dev.py condition-r2
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lasa_dev.py lasa5 [--only "NAME;..."]
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lasa_dev.py grid [--only "NAME;NAME..."]
        [--variant 'LABEL={"shrinkage": 0.5, ...}' ...]

``split`` (lead a): for every fold, the reproduction of the default :class:`ThesisReproducer`
resampled on the held-out time stamps, and three errors against the held-out demonstration (mm):
``time`` = RMS over time stamps of |rep(t) - held(t)| (position at the same time); ``dtw`` = the
same after re-timing the reproduction to the held-out demonstration by DTW on the positions
(RMS over the warping path's pairs: the shape part); ``rmse`` = the issue's metric (nearest
held-out sample). ``timing share`` = 1 - dtw^2 / time^2. It also prints the rmse of the
default's reproduction re-timed by the DTW path (each held-out time stamp gets the mean of its
matched reproduction points), i.e. what a perfect phase variable could give.

``grid`` (leads b-d): every named variant of ``ThesisReproducer`` (weights of the start-marker
and start-frame constraints, covariance shrinkage, the start frame's scale, h and dt, extra
start frames) scored on the development folds, per shape and mean, beside the previous
default (session 6, the base of every variant), today's default and the naive baseline.
``--variant`` entries are applied on top of the previous default too.

``condition`` (lasa4): the per-slice Gaussians conditioned on the observed start
(``ThesisReproducer(condition=..., condition_on=..., ridge=..., inflation=...)``), each variant
with the mean paired difference to today's default over the 63 development folds, the folds it
lowers and the Wilcoxon signed-rank p-value. ``condition-r2``: how well the start predicts a
held-out path on its own (see :func:`condition_r2`).

``lasa5``: where the session-7 default errs against the baseline (fifths of the reproduction),
then fusion rules (the constraints as correlated estimators), robust demonstration weights and
the drawing's duration as a cue (the duration frame, adopted), each against the session-7
default with the gate numbers (shapes and folds lowered, Wilcoxon p); see :func:`lasa5`.

``extras``: variants outside the reproducer's settings (the DBN indexed by normalised arc
length instead of DTW time, a second DTW pass to the barycentre, covariances smoothed over
time), swapped in inside this script only.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
import warnings

import numpy as np

from mmlearn.models.imitation.lasa import (DEVELOPMENT_SHAPES, ThesisReproducer, baseline_reproducer,
                                           evaluate_shape, leave_one_out, load_shape, resample_to, rmse_mm)


def _dtw_path(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    from dtaidistance import dtw_ndim

    return np.asarray(dtw_ndim.warping_path(np.ascontiguousarray(a, dtype=np.double),
                                            np.ascontiguousarray(b, dtype=np.double), use_c=True))


def split(shapes) -> None:
    rep_fn = ThesisReproducer()
    rows = []
    print(f"{'shape':17s} {'time':>7s} {'dtw':>7s} {'rmse':>7s} {'timing share':>12s} {'rmse re-timed':>13s}")
    for name in shapes:
        demos = load_shape(name)
        acc = []
        for k, train, held in leave_one_out(demos):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t, x = rep_fn(train, held)
            rep = resample_to(t - t[0], x, held.t - held.t[0])
            e_time = np.sqrt(np.mean(np.sum((rep - held.hand) ** 2, axis=1)))
            p = _dtw_path(held.hand, rep)
            e_dtw = np.sqrt(np.mean(np.sum((held.hand[p[:, 0]] - rep[p[:, 1]]) ** 2, axis=1)))
            # re-timed reproduction: every held-out stamp i gets the mean of its matched rep points
            cnt = np.bincount(p[:, 0], minlength=held.T).astype(float)
            ret = np.zeros_like(held.hand)
            np.add.at(ret, p[:, 0], rep[p[:, 1]])
            ret /= cnt[:, None]
            acc.append((e_time, e_dtw, rmse_mm(rep, held.hand), rmse_mm(ret, held.hand)))
        a = np.mean(acc, axis=0)
        rows.append(a)
        print(f"{name:17s} {a[0]:7.3f} {a[1]:7.3f} {a[2]:7.3f} {1 - a[1] ** 2 / a[0] ** 2:12.2f} {a[3]:13.3f}")
    m = np.mean(rows, axis=0)
    print(f"{'mean':17s} {m[0]:7.3f} {m[1]:7.3f} {m[2]:7.3f} {1 - m[1] ** 2 / m[0] ** 2:12.2f} {m[3]:13.3f}")


S6 = {"objects": ("target", "start", "frame"), "full_covariance": True, "shrinkage": 0.0}
"""The previous default (session 6): the base of the one-at-a-time variants."""

FS = ("target", "start", "frame", "frame_scale")


def _variants() -> dict[str, dict]:
    """The named variants: one change at a time from the previous default :data:`S6`, then the
    combinations tried; ``default`` is today's :class:`ThesisReproducer` default."""
    v: dict[str, dict] = {"s6 (previous default)": {}, "default": None}
    for o in ("frame", "start", "target"):
        for w in (0.25, 0.5, 2.0, 4.0):
            v[f"weight_{o}={w:g}"] = {"weights": {o: w}}
    for lam in (0.25, 0.5, 1.0):
        v[f"shrinkage={lam:g}"] = {"shrinkage": lam}
    v["diagonal"] = {"full_covariance": False}
    for m in ("rotation", "scale"):
        v[f"frame_mode={m}"] = {"frame_mode": m}
    for h in (0.01, 0.04, 0.08):
        v[f"h={h:g}"] = {"h": h}
    for dt, h in ((0.01, 0.01), (0.01, 0.02), (0.04, 0.04)):
        v[f"dt={dt:g},h={h:g}"] = {"dt": dt, "h": h}
    for f in ("derivative", "position"):
        v[f"align_features={f}"] = {"align_features": f}
    three = S6["objects"]
    v["+frame_scale"] = {"objects": FS}
    v["+frame_rotation"] = {"objects": three + ("frame_rotation",)}
    v["+frame_scale+frame_rotation"] = {"objects": three + ("frame_scale", "frame_rotation")}
    v["frame->frame_scale"] = {"objects": ("target", "start", "frame_scale")}
    for lam in (0.25, 0.5, 0.75, 1.0):
        v[f"+frame_scale,shrinkage={lam:g}"] = {"objects": FS, "shrinkage": lam}
    v["+frame_scale,diagonal"] = {"objects": FS, "full_covariance": False}
    v["+frame_scale,derivative"] = {"objects": FS, "align_features": "derivative"}
    v["+frame_scale,shrinkage=0.5,derivative"] = {"objects": FS, "shrinkage": 0.5, "align_features": "derivative"}
    for o in ("target", "start", "frame", "frame_scale"):
        for w in (0.5, 2.0):
            v[f"+frame_scale,shrinkage=0.5,weight_{o}={w:g}"] = {"objects": FS, "shrinkage": 0.5, "weights": {o: w}}
    return {k: (None if kw is None else {**S6, **kw}) for k, kw in v.items()}


def grid(shapes, only=None, extra=None) -> None:
    variants = _variants()
    if only:
        variants = {k: variants[k] for k in only}
    for spec in extra or ():
        i = spec.find("={")
        if i < 0:
            raise SystemExit(f"--variant {spec!r}: expected LABEL={{json}}")
        label, kw = spec[:i], json.loads(spec[i + 1:])
        if "objects" in kw:
            kw["objects"] = tuple(kw["objects"])
        variants[label] = kw
    demos = {n: load_shape(n) for n in shapes}
    base = {n: evaluate_shape(n, baseline_reproducer, demos=demos[n]).rmse_mm for n in shapes}
    bmean = float(np.mean(list(base.values())))
    print(f"{'variant':34s} {'mean':>6s} {'end':>6s} {'vs base':>7s}  " + " ".join(f"{n[:7]:>7s}" for n in shapes))
    print(f"{'baseline':34s} {bmean:6.3f} {0:6.3f} {0:7.1%}  " + " ".join(f"{base[n]:7.3f}" for n in shapes))
    for label, kw in variants.items():
        t0 = time.perf_counter()
        rep = ThesisReproducer() if kw is None else ThesisReproducer(**kw)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = {n: evaluate_shape(n, rep, demos=demos[n]) for n in shapes}
        m = float(np.mean([r.rmse_mm for r in res.values()]))
        e = float(np.mean([r.end_error_mm for r in res.values()]))
        print(f"{label:34s} {m:6.3f} {e:6.3f} {1 - m / bmean:7.1%}  "
              + " ".join(f"{res[n].rmse_mm:7.3f}" for n in shapes)
              + f"  ({time.perf_counter() - t0:.1f} s)", flush=True)


@contextlib.contextmanager
def _alignment(kind: str):
    """Swap :func:`mmlearn.models.imitation.dbn.align_demonstrations` (looked up at call time by
    ``ThesisReproducer.learn``) for a study variant, inside this benchmark only:
    ``"arc"``: no DTW, every demonstration resampled at uniform normalised arc length (the DBN
    indexed by progress along the path, the reference's median duration); ``"barycentre"``: DTW
    to the reference, then a second DTW pass of every demonstration to the mean of the first."""
    import mmlearn.models.imitation.dbn as imi
    from mmlearn.models.imitation.types import Demonstration

    real = imi.align_demonstrations

    def arc(demos, *, dt=None, features="both", **kw):
        demos = list(demos)
        n = int(round(float(np.median([d.duration for d in demos])) / dt)) + 1
        u = np.linspace(0.0, 1.0, n)
        out = []
        for d in demos:
            s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(d.hand, axis=0), axis=1))]
            s /= s[-1]
            keep = np.r_[True, np.diff(s) > 1e-12]

            def f(a):
                return np.stack([np.interp(u, s[keep], a[keep, c]) for c in range(a.shape[1])], axis=1)
            out.append(Demonstration(t=dt * np.arange(n), hand=f(d.hand),
                                     objects={k: f(v) for k, v in d.objects.items()}, meta=dict(d.meta)).validate())
        return out

    def barycentre(demos, *, dt=None, features="both", **kw):
        demos = list(demos)
        al = real(demos, dt=dt, features=features, **kw)
        m = Demonstration(t=al[0].t, hand=np.mean([d.hand for d in al], axis=0),
                          objects={k: np.mean([d.objects[k] for d in al], axis=0) for k in al[0].objects}).validate()
        return real([m] + demos, dt=dt, features=features, reference=0, **kw)[1:]

    imi.align_demonstrations = {"arc": arc, "barycentre": barycentre}[kind]
    try:
        yield
    finally:
        imi.align_demonstrations = real


class _SmoothedCovariances(ThesisReproducer):
    """ThesisReproducer whose tempered covariances are also smoothed over the slices by a
    Gaussian of ``smooth`` seconds (study only)."""

    def __init__(self, *, smooth: float, **kw):
        super().__init__(**kw)
        self.smooth = smooth

    def _temper(self, name, var):
        from scipy.ndimage import gaussian_filter1d

        return gaussian_filter1d(super()._temper(name, var), self.smooth / self.dt, axis=0, mode="nearest")


def extras(shapes) -> None:
    """Variants outside ThesisReproducer's settings: arc-length indexing, a barycentre DTW pass,
    covariances smoothed over time (development shapes, mean rmse / end error, mm)."""
    demos = {n: load_shape(n) for n in shapes}

    def score(rep):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = [evaluate_shape(n, rep, demos=demos[n]) for n in shapes]
        return np.mean([r.rmse_mm for r in res]), np.mean([r.end_error_mm for r in res])

    s6 = ThesisReproducer(**S6)
    rows = [("s6 (previous default)", None, s6), ("default", None, ThesisReproducer()),
            ("s6, arc-length indexing", "arc", s6), ("default, arc-length indexing", "arc", ThesisReproducer()),
            ("default, barycentre DTW pass", "barycentre", ThesisReproducer())]
    for sm in (0.05, 0.1, 0.2):
        rows.append((f"default, covariances smoothed {sm:g} s", None, _SmoothedCovariances(smooth=sm)))
    for label, kind, rep in rows:
        with (_alignment(kind) if kind else contextlib.nullcontext()):
            m, e = score(rep)
        print(f"{label:40s} rmse {m:.3f} mm  end {e:.3f} mm", flush=True)


def _condition_variants() -> dict[str, dict]:
    """Conditioning on the start (lasa4): which constraints are conditioned, on what, with
    which ridge and residual-covariance inflation (on top of today's default)."""
    v: dict[str, dict] = {}
    sets = {"target": ("target",), "target,start": ("target", "start"), "frames": ("frame", "frame_scale"),
            "all": ("target", "start", "frame", "frame_scale")}
    for on in ("position", "polar"):
        for label, cond in sets.items():
            v[f"cond[{label}] on {on}"] = {"condition": cond, "condition_on": on}
        v[f"cond[target] on {on}, no start marker"] = {
            "condition": ("target",), "condition_on": on, "weights": {"start": 1e-6}}
    return v


def condition(shapes, only=None, extra=None, out=None) -> None:
    """Every conditioning variant scored on the development folds: mean rmse / end error (mm),
    % below the baseline, the mean paired difference to today's default over the 63 folds, the
    number of folds where the variant is lower and the Wilcoxon signed-rank p-value."""
    from scipy.stats import wilcoxon

    variants = _condition_variants()
    if only is not None:
        variants = {k: variants[k] for k in only if k}
    for spec in extra or ():
        i = spec.find("={")
        if i < 0:
            raise SystemExit(f"--variant {spec!r}: expected LABEL={{json}}")
        kw = json.loads(spec[i + 1:])
        for k in ("objects", "condition"):
            if k in kw:
                kw[k] = tuple(kw[k])
        variants[spec[:i]] = kw
    demos = {n: load_shape(n) for n in shapes}

    def folds(rep):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = [evaluate_shape(n, rep, demos=demos[n]) for n in shapes]
        return (np.array([f.rmse_mm for r in res for f in r.folds]), np.array([f.end_error_mm for r in res for f in r.folds]),
                np.array([r.rmse_mm for r in res]))

    base = folds(baseline_reproducer)[2].mean()
    ref, ref_end, ref_shape = folds(ThesisReproducer())
    print(f"{'variant':44s} {'rmse':>6s} {'end':>6s} {'vs base':>7s} {'d/default':>9s} {'better':>6s} {'p':>7s}")
    print(f"{'baseline':44s} {base:6.3f}")
    print(f"{'default':44s} {ref_shape.mean():6.3f} {ref_end.mean():6.3f} {1 - ref_shape.mean() / base:7.1%}", flush=True)
    for label, kw in variants.items():
        t0 = time.perf_counter()
        r, e, sh = folds(ThesisReproducer(**kw))
        d = r - ref
        p = wilcoxon(r, ref).pvalue if np.any(d != 0) else 1.0
        print(f"{label:44s} {sh.mean():6.3f} {e.mean():6.3f} {1 - sh.mean() / base:7.1%} {d.mean():+9.4f} "
              f"{int(np.sum(d < 0)):3d}/{len(d):2d} {p:7.3f}  ({time.perf_counter() - t0:.0f} s)", flush=True)
        if out:
            with open(out, "a") as f:
                f.write(json.dumps({"label": label, "kw": kw, "rmse_mm": float(sh.mean()), "end_error_mm": float(e.mean()),
                                    "fold_rmse_mm": r.tolist(), "default_fold_rmse_mm": ref.tolist(),
                                    "shape_rmse_mm": sh.tolist(), "p": float(p)}) + "\n")


def condition_r2(shapes) -> None:
    """How much of a held-out drawing's path the start predicts (diagnostic for lasa4): all 7
    demonstrations aligned together by DTW (the held-out one included: a diagnostic, not a
    method), then per fold and slice the held-out's target constraint ``r = target - hand``
    predicted from the other 6 by (a) their mean, (b) their start-frame mean mapped by the
    held-out's start frame, (c) the Gaussian conditional on the held-out start (ridge 0/1/3,
    position covariates), (d) the start-frame mean conditioned on the start (polar, ridge 1).
    Prints per shape and method the RMS prediction error at the same aligned time (mm, over
    slices and folds) / the issue's metric of the predicted path (nearest held-out sample, mm,
    mean over folds)."""
    from mmlearn.models.imitation.dbn import align_demonstrations
    from mmlearn.models.imitation.lasa import (condition_on_start, start_covariates, start_frame, to_start_frame,
                                               with_start_marker)

    labels = ["mean", "frame", "cond r0", "cond r1", "cond r3", "frame+cond"]
    print(f"{'shape':17s} " + " ".join(f"{x:>11s}" for x in labels))
    acc = []
    for name in shapes:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            raw = load_shape(name)
            al = align_demonstrations([with_start_marker(d) for d in raw], dt=0.02, features="both")
        t = al[0].t - al[0].t[0]
        r = np.stack([d.objects["target"] - d.hand for d in al])
        u = np.stack([-to_start_frame(d).hand for d in al])
        starts = np.stack([d.hand[0] for d in al])
        err = {k: [] for k in labels}
        for k in range(len(al)):
            tr = [j for j in range(len(al)) if j != k]
            S = start_frame(starts[k])
            C, c = start_covariates(starts[tr], starts[k])
            Cp, cp = start_covariates(starts[tr], starts[k], kind="polar")
            pred = {"mean": r[tr].mean(0), "frame": u[tr].mean(0) @ S.T}
            for rg in (0, 1, 3):
                pred[f"cond r{rg}"] = condition_on_start(t, r[tr], C, c, h=1e-3, ridge=rg)[0]
            pred["frame+cond"] = condition_on_start(t, u[tr], Cp, cp, h=1e-3, ridge=1)[0] @ S.T
            for lab in labels:
                err[lab].append((np.mean(np.sum((pred[lab] - r[k]) ** 2, axis=1)),
                                 rmse_mm(al[k].objects["target"] - pred[lab], raw[k].hand)))
        row = [float(np.sqrt(np.mean([e[0] for e in err[lab]]))) for lab in labels]
        row2 = [float(np.mean([e[1] for e in err[lab]])) for lab in labels]
        acc.append((row, row2))
        print(f"{name:17s} " + " ".join(f"{x:5.3f}/{y:5.3f}" for x, y in zip(row, row2)), flush=True)
    m = np.mean(acc, axis=0)
    print(f"{'mean':17s} " + " ".join(f"{x:5.3f}/{y:5.3f}" for x, y in zip(m[0], m[1])))


# =============================================================================================
# lasa5: fusion rules, robust demonstration weights, the duration as a cue (development only)
def _frame(s, mode, T=None):
    from mmlearn.models.imitation.lasa import start_frame

    return start_frame(s, (0.0, 0.0), mode=mode, duration=T)


def _on_model_time(t, path, held, dt):
    """``(t, x)`` of a per-slice path reproduced for the held-out duration (the slice timing of
    :func:`mmlearn.models.imitation.lasa.fused_path`)."""
    n_steps = int(round(held.duration / dt))
    k = np.clip(np.searchsorted(t, np.arange(1, n_steps + 1) * dt * float(t[-1]) / held.duration - 1e-9),
                0, len(t) - 1)
    return np.arange(n_steps + 1) * dt, np.vstack([held.hand[0][None], path[k]])


class _Predictors:
    """The hand path each constraint predicts alone for a start ``s`` (target: the mean path;
    start: the mean path shifted by the start; frames: the mean in the start frame mapped by
    ``s``'s frame), plain means over the aligned demonstrations."""

    def __init__(self, H, S0, preds):
        G = H.shape[0]
        self.P = {}
        for p in preds:
            if p == "target":
                self.P[p] = (lambda m: lambda s: m)(H.mean(0))
            elif p == "start":
                self.P[p] = (lambda m: lambda s: m + s)((H - S0[:, None]).mean(0))
            else:
                mode = "similarity" if p == "frame" else p.split("_")[1]
                U = np.stack([H[g] @ np.linalg.inv(_frame(S0[g], mode)).T for g in range(G)]).mean(0)
                self.P[p] = (lambda U, mode: lambda s: U @ _frame(s, mode).T)(U, mode)


class _BlueFusion:
    """The constraints fused as correlated estimators of the hand (best linear unbiased
    combination): per slice the joint covariance of every constraint's leave-one-demonstration-
    out prediction error over the training demonstrations (Parzen window ``hw`` s), shrunk by
    ``ridge`` towards its diagonal (1 = independent constraints), ``floor`` mm^2 added; ``iso``:
    one scalar weight per constraint (errors' dot products) instead of 2x2 blocks; ``clip``:
    negative scalar weights set to 0."""

    preds = ("target", "start", "frame", "frame_scale")

    def __init__(self, *, hw=0.02, ridge=0.0, iso=False, floor=1e-3, clip=False, dt=0.02):
        self.hw, self.ridge, self.iso, self.floor, self.clip, self.dt = hw, ridge, iso, floor, clip, dt

    def __call__(self, train, held):
        from mmlearn.models.imitation.dbn import align_demonstrations, parzen_weights
        from mmlearn.models.imitation.lasa import with_start_marker

        al = align_demonstrations([with_start_marker(d) for d in train], dt=self.dt, features="both")
        H = np.stack([d.hand for d in al])
        S0 = np.stack([d.objects["start"][0] for d in al])
        G, T, _ = H.shape
        n = len(self.preds)
        E = np.zeros((G, T, n, 2))
        for g in range(G):
            keep = [j for j in range(G) if j != g]
            P = _Predictors(H[keep], S0[keep], self.preds).P
            for i, p in enumerate(self.preds):
                E[g, :, i] = H[g] - P[p](S0[g])
        t = al[0].t
        W = parzen_weights(t, t, h=self.hw, G=G)
        P = _Predictors(H, S0, self.preds).P
        s = held.hand[0]
        if self.iso:
            C = np.einsum("st,gtia,gtja->sij", W, E, E) / 2 + self.floor * np.eye(n)
            C = (1 - self.ridge) * C + self.ridge * np.einsum("sii->si", C)[:, :, None] * np.eye(n)
            w = np.linalg.solve(C, np.ones((T, n, 1)))[:, :, 0]
            w /= w.sum(1, keepdims=True)
            if self.clip:
                w = np.clip(w, 0, None)
                w /= w.sum(1, keepdims=True)
            path = np.einsum("ti,tia->ta", w, np.stack([P[p](s) for p in self.preds], 1))
        else:
            Ef = E.reshape(G, T, 2 * n)
            C = np.einsum("st,gta,gtb->sab", W, Ef, Ef) + self.floor * np.eye(2 * n)
            C = (1 - self.ridge) * C + self.ridge * np.einsum("sii->si", C)[:, :, None] * np.eye(2 * n)
            Hm = np.tile(np.eye(2), (n, 1))
            Ci = np.linalg.inv(C)
            A = np.einsum("ai,sab,bj->sij", Hm, Ci, Hm)
            b = np.einsum("ai,sab,sb->si", Hm, Ci, np.concatenate([P[p](s) for p in self.preds], 1))
            path = np.linalg.solve(A, b[:, :, None])[:, :, 0]
        return _on_model_time(t, path, held, self.dt)


class _ProductFusion:
    """The thesis' product of Gaussians re-written for the study (equal to the default
    ThesisReproducer's closed form when ``robust`` is off and ``preds`` is the session-7 set),
    with two options: ``robust``: each training demonstration weighted by a Student-t weight
    ``(nu + 2) / (nu + d2)`` of its mean squared Mahalanobis deviation d2 (5 reweighting
    passes; robust learning against an odd demonstration); extra constraints ``"duration"``
    (the target constraint in world axes with unit = the drawing's duration, mm/s) and
    ``"dur_start"`` (the start constraint in duration units), placed with the held-out
    duration; ``"frame_duration"`` is the duration frame of ThesisReproducer."""

    def __init__(self, *, preds=("target", "start", "frame", "frame_scale"), shrink=0.5, robust=False, nu=4.0,
                 h=0.02, dt=0.02):
        self.preds, self.shrink, self.robust, self.nu, self.h, self.dt = preds, shrink, robust, nu, h, dt

    def _moments(self, V, a, W, min_var):
        w = a[:, None, None] * W[None]
        c0 = V.reshape(-1, 2).mean(0)
        Vc = V - c0
        m1 = np.einsum("gst,gtd->sd", w, Vc)
        m2 = np.einsum("gst,gtd,gte->sde", w, Vc, Vc)
        den = np.maximum(1 - np.einsum("gst->s", w * w), 1e-12)
        cov = (m2 - m1[:, :, None] * m1[:, None, :]) / den[:, None, None]
        cov = 0.5 * (cov + cov.swapaxes(1, 2)) + min_var * np.eye(2)
        diag = np.einsum("sii->si", cov)[:, :, None] * np.eye(2)
        return m1 + c0, (1 - self.shrink) * cov + self.shrink * diag

    def _components(self, H, S0, Tg, t, s, Tq, a):
        from mmlearn.models.imitation.dbn import parzen_weights

        G = H.shape[0]
        W = parzen_weights(t, t, h=self.h, G=1)
        out = []
        for p in self.preds:
            off = 0.0
            if p == "target":
                V, mv, M = -H, 1e-6, np.eye(2)
            elif p == "start":
                V, mv, M, off = S0[:, None] - H, 1e-6, np.eye(2), s
            elif p == "duration":
                V, mv, M = -H / Tg[:, None, None], 1e-6 / np.mean(Tg ** 2), Tq * np.eye(2)
            elif p == "dur_start":
                V, mv, M, off = (S0[:, None] - H) / Tg[:, None, None], 1e-6 / np.mean(Tg ** 2), Tq * np.eye(2), s
            else:
                mode = "similarity" if p == "frame" else p.split("_")[1]
                V = np.stack([-H[g] @ np.linalg.inv(_frame(S0[g], mode, Tg[g])).T for g in range(G)])
                unit2 = np.mean(Tg ** 2) if mode == "duration" else np.mean(np.sum(S0 ** 2, 1))
                mv, M = 1e-6 / unit2, _frame(s, mode, Tq)
            mu, cov = self._moments(V, a, W, mv)
            out.append((off - mu @ M.T, np.einsum("ij,sjk,lk->sil", M, cov, M), V))
        return out

    def __call__(self, train, held):
        from mmlearn.models.imitation.dbn import align_demonstrations
        from mmlearn.models.imitation.lasa import with_start_marker

        al = align_demonstrations([with_start_marker(d) for d in train], dt=self.dt, features="both")
        H = np.stack([d.hand for d in al])
        S0 = np.stack([d.objects["start"][0] for d in al])
        Tg = np.array([d.duration for d in train])
        t = al[0].t
        G = len(al)
        a = np.full(G, 1.0 / G)
        s = held.hand[0]
        if self.robust:
            for _ in range(5):
                d2 = np.zeros(G)
                comps = self._components(H, S0, Tg, t, s, held.duration, a)
                for _, _, V in comps:
                    mu = np.einsum("g,gtd->td", a, V)
                    C = np.einsum("g,gtd,gte->tde", a, V - mu, V - mu) * G / (G - 1) + 1e-6 * np.eye(2)
                    e = V - mu
                    d2 += np.einsum("gti,tij,gtj->gt", e, np.linalg.inv(C), e).mean(1) / len(comps)
                a = (self.nu + 2) / (self.nu + d2)
                a /= a.sum()
        Psum, b = 0.0, 0.0
        for pred, cov, _ in self._components(H, S0, Tg, t, s, held.duration, a):
            P = np.linalg.inv(cov)
            Psum = Psum + P
            b = b + np.einsum("sij,sj->si", P, pred)
        return _on_model_time(t, np.linalg.solve(Psum, b[:, :, None])[:, :, 0], held, self.dt)


class _DurationUnknown(ThesisReproducer):
    """The default (with the duration frame) placed with the training drawings' median
    duration instead of the held-out one (reproduced for the held-out duration): how much of
    the duration frame's gain is the duration itself."""

    def __call__(self, train, held):
        from mmlearn.models.imitation.dbn import reproduce_cartesian

        m = self.learn(train, start=held.hand[0], duration=float(np.median([d.duration for d in train])))
        obj = {"target": held.objects["target"][0], "start": held.hand[0]}
        obj.update({o: held.objects["target"][0] for o in self.objects if o.startswith("frame")})
        return reproduce_cartesian(m, held.hand[0], obj, duration=held.duration, dt=self.dt, gain=self.gain)


S7 = ("target", "start", "frame", "frame_scale")
"""The session-7 default's constraint objects (the reference of the lasa5 study)."""


def _lasa5_variants() -> dict:
    v = {}
    for kw in (dict(iso=True, hw=0.02), dict(iso=False, hw=0.02), dict(iso=True, hw=0.1), dict(iso=False, hw=0.1),
               dict(iso=True, hw=0.1, clip=True), dict(iso=False, ridge=1.0, floor=1e-6),
               dict(iso=False, ridge=0.5, floor=1e-6), dict(iso=True, ridge=1.0, floor=1e-6)):
        v["blue " + ",".join(f"{k}={x:g}" for k, x in kw.items())] = _BlueFusion(**kw)
    v["product re-written (= session 7)"] = _ProductFusion()
    for nu in (4.0, 1.0, 10.0):
        v[f"robust demo weights nu={nu:g}"] = _ProductFusion(robust=True, nu=nu)
    v["+duration (world axes, unit T)"] = _ProductFusion(preds=S7 + ("duration",))
    v["+dur_start (start constraint / T)"] = _ProductFusion(preds=S7 + ("dur_start",))
    v["+duration +dur_start"] = _ProductFusion(preds=S7 + ("duration", "dur_start"))
    v["+frame_duration (new default)"] = ThesisReproducer(objects=S7 + ("frame_duration",))
    v["+dur_start, shrinkage 1"] = _ProductFusion(preds=S7 + ("dur_start",), shrink=1.0)
    v["+dur_start, shrinkage 0"] = _ProductFusion(preds=S7 + ("dur_start",), shrink=0.0)
    v["diag: +frame_duration, median training T"] = _DurationUnknown()
    v["diag: +frame_rotation (unit 1 mm)"] = ThesisReproducer(objects=S7 + ("frame_rotation",))
    return v


def lasa5(shapes, only=None) -> None:
    """lasa5 study: every variant against the session-7 default (target + start + frame +
    frame_scale) on the development folds: mean rmse / end error (mm), the shapes and folds it
    lowers, the Wilcoxon signed-rank p over the 63 paired folds; first the error split by
    fifths of the reproduction (mean squared nearest distance, mm^2) against the baseline."""
    from scipy.spatial import cKDTree
    from scipy.stats import wilcoxon

    demos = {n: load_shape(n) for n in shapes}
    s7 = ThesisReproducer(objects=S7)
    print("error by fifths of the reproduction (mean squared nearest distance, mm^2), session 7 | baseline; "
          "folds where session 7 beats the baseline")
    acc = []
    for n in shapes:
        rows = []
        for k, train, held in leave_one_out(demos[n]):
            r = []
            for f in (s7, baseline_reproducer):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t, x = f(train, held)
                d, _ = cKDTree(held.hand).query(resample_to(t - t[0], x, held.t - held.t[0]))
                r.append([np.sqrt(np.mean(d ** 2))] + [np.mean(b) for b in np.array_split(d ** 2, 5)])
            rows.append(r)
        a = np.array(rows)
        acc.append(a.mean(0))
        m = a.mean(0)
        print(f"{n:17s} {m[0, 0]:.3f} | {m[1, 0]:.3f}  " + " ".join(f"{x:5.2f}" for x in m[0, 1:]) + " | "
              + " ".join(f"{x:5.2f}" for x in m[1, 1:]) + f"  {int(np.sum(a[:, 0, 0] < a[:, 1, 0]))}/7", flush=True)
    m = np.mean(acc, axis=0)
    print(f"{'mean':17s} {m[0, 0]:.3f} | {m[1, 0]:.3f}  " + " ".join(f"{x:5.2f}" for x in m[0, 1:]) + " | "
          + " ".join(f"{x:5.2f}" for x in m[1, 1:]))

    def folds(rep):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = [evaluate_shape(n, rep, demos=demos[n]) for n in shapes]
        return (np.array([f.rmse_mm for r in res for f in r.folds]), np.array([r.rmse_mm for r in res]),
                float(np.mean([r.end_error_mm for r in res])))

    ref, ref_sh, ref_end = folds(s7)
    print(f"\n{'variant':40s} {'rmse':>6s} {'end':>6s} {'change':>7s} {'shapes':>6s} {'folds':>6s} {'p':>6s}  per shape")
    print(f"{'session 7 default':40s} {ref_sh.mean():6.3f} {ref_end:6.3f}  " + " ".join(f"{x:.3f}" for x in ref_sh))
    for label, rep in _lasa5_variants().items():
        if only and label not in only:
            continue
        r, sh, e = folds(rep)
        p = wilcoxon(r, ref).pvalue if np.any(r != ref) else 1.0
        print(f"{label:40s} {sh.mean():6.3f} {e:6.3f} {sh.mean() / ref_sh.mean() - 1:+7.1%} "
              f"{int(np.sum(sh < ref_sh)):3d}/{len(sh)} {int(np.sum(r < ref)):3d}/{len(r)} {p:6.3f}  "
              + " ".join(f"{x:.3f}" for x in sh), flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=("split", "grid", "extras", "condition", "condition-r2", "lasa5"))
    ap.add_argument("--only", default=None, help="grid, condition: variant names separated by ;")
    ap.add_argument("--out", default=None, help="condition: append every variant's fold results to this JSON Lines file")
    ap.add_argument("--variant", action="append", default=[],
                    help='grid: an extra variant NAME={"keyword": value, ...} (JSON keyword arguments '
                         'of ThesisReproducer); repeatable')
    a = ap.parse_args(argv)
    shapes = list(DEVELOPMENT_SHAPES)
    if a.what == "split":
        split(shapes)
    elif a.what == "extras":
        extras(shapes)
    elif a.what == "condition-r2":
        condition_r2(shapes)
    elif a.what == "lasa5":
        lasa5(shapes, None if a.only is None else [s.strip() for s in a.only.split(";")])
    elif a.what == "condition":
        condition(shapes, None if a.only is None else [s.strip() for s in a.only.split(";")], a.variant, a.out)
    else:
        grid(shapes, None if a.only is None else [s.strip() for s in a.only.split(";")], a.variant)
    return 0


if __name__ == "__main__":
    sys.exit(main())
