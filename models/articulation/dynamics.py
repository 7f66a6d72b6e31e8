"""Mechanism dynamics learned while operating: damping, Coulomb friction and a closing spring
from the wrist force and the hook's motion along the learned model (thesis outlook,
Sec. 9.1: "learn friction and damping profiles and include this information in the learned
model ... estimate the torque required to open a drawer and detect whether it is jammed").

The learned link model (revolute or prismatic) gives the configuration q of every hook
position (``link.inverse``) and the model's tangent dp/dq (``link.jacobian``). The
generalised force the robot applies along the mechanism is the wrist force projected on
that tangent, tau = -F . dp/dq (F: force of the mechanism on the hook, world frame): a
torque in N m for a revolute model (q in rad), a force in N for a prismatic one (q in m).
Its rate and acceleration come from local quadratic fits of q(t). The mechanism's model is

    tau = b qdot + f s(qdot) + k (q - q_ref) + I qddot + noise,

with viscous damping b (N m s/rad or N s/m), Coulomb friction f (N m or N), a spring k
(N m/rad or N/m) pulling towards the closed configuration q_ref (where the pull began) and
the moving part's effective inertia I (kg m^2 or kg, a nuisance term). The friction's shape
s(qdot) is sign(qdot) (ideal Coulomb friction) or, with a regularisation speed v_f > 0,
tanh(qdot / v_f): Coulomb friction that builds up over the first few v_f of speed, as the
simulated joints' friction does (:class:`mmlearn.systems.common.JointFriction`, v_f =
0.02 m/s or rad/s). With the ideal sign the growth of a regularised friction with speed reads
as damping (a drawer's 1-2 N of friction growing from 76 % to 100 % between 2 and 8 cm/s
adds 3-8 N s/m). :func:`fit_dynamics`
is a Bayesian linear regression: independent zero-mean Gaussian priors on the coefficients,
the noise level by empirical Bayes (residual variance), a robust start (Huber weights) and
3-sigma outlier rejection (a hook that slips, the end stop). It returns :class:`MechanismDynamics`:
the posterior means and standard deviations, the covariance, and a friction profile along q
(the residual resistance in bins of q after the viscous, spring and inertial terms: where
the mechanism is stiffer in one part of its travel). Only samples where the mechanism moves
(|qdot| above ``min_rate`` and a quarter of the median rate) enter: at rest the Coulomb force is anywhere within +-f.

Damping and friction are told apart only if the speed varies during the pull; the opening
controller therefore modulates its pulling speed (see
:class:`mmlearn.systems.articulation.jam_monitor.DynamicsMonitor`).

Storage: :meth:`MechanismDynamics.to_dict` is the optional ``dynamics`` section of a saved
articulation model (:func:`save_model_with_dynamics`, :func:`load_model_with_dynamics`), and
:func:`sdf_with_dynamics` writes it into the exported SDFormat joint as
``<dynamics><damping>``, ``<friction>``, ``<spring_reference>`` and ``<spring_stiffness>``
(Drake's parser reads damping and the spring; it ignores ``<friction>``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["MechanismDynamics", "fit_dynamics", "generalized_samples", "local_derivatives",
           "local_state",
           "dynamics_units", "save_model_with_dynamics", "load_model_with_dynamics",
           "sdf_with_dynamics", "path_opening", "friction_shape", "COEFFICIENTS"]

#: the regression's coefficients, in the order of its feature vector
COEFFICIENTS = ("damping", "friction", "stiffness", "inertia")

#: prior standard deviations of the coefficients (revolute: N m s/rad, N m, N m/rad, kg m^2;
#: prismatic: N s/m, N, N/m, kg): broad, a few times the largest household mechanism's
_PRIOR_STD = {"revolute": (20.0, 20.0, 20.0, 2.0), "prismatic": (200.0, 100.0, 200.0, 20.0)}


def friction_shape(qdot, friction_velocity: float = 0.0) -> np.ndarray:
    """The Coulomb friction's dependence on the rate, between -1 and 1: sign(qdot) for
    ``friction_velocity`` 0 (ideal Coulomb friction), else tanh(qdot / friction_velocity)
    (regularised: the friction builds up over the first few ``friction_velocity`` of speed,
    rad/s or m/s)."""
    qdot = np.asarray(qdot, float)
    if friction_velocity < 0 or not math.isfinite(friction_velocity):
        raise ValueError(f"friction_velocity must be a finite number >= 0, got "
                         f"{friction_velocity!r}")
    if friction_velocity == 0:
        return np.sign(qdot)
    return np.tanh(qdot / friction_velocity)


def dynamics_units(joint: str) -> dict:
    """Units of the coefficients for a ``"revolute"`` or ``"prismatic"`` joint."""
    if joint == "revolute":
        return {"q": "rad", "damping": "N m s/rad", "friction": "N m",
                "stiffness": "N m/rad", "inertia": "kg m^2", "force": "N m"}
    if joint == "prismatic":
        return {"q": "m", "damping": "N s/m", "friction": "N", "stiffness": "N/m",
                "inertia": "kg", "force": "N"}
    raise ValueError(f"joint must be revolute or prismatic, got {joint!r}")


@dataclass
class MechanismDynamics:
    """Learned dynamics of one joint (units: :func:`dynamics_units` of ``joint``).

    Attributes:
        joint: "revolute" or "prismatic" (the learned model's kind).
        damping, friction, stiffness, inertia: posterior means of b, f, k, I.
        damping_std, friction_std, stiffness_std, inertia_std: their posterior standard
            deviations.
        spring_reference: configuration the spring pulls towards (the closed one; 0 in the
            model's opening coordinate), rad or m.
        noise_std: residual standard deviation of the generalised force, N m or N.
        covariance: 4 x 4 posterior covariance of (b, f, k, I).
        n_samples: samples used (moving, not rejected).
        q_range: [min, max] opening covered by the samples, rad or m.
        profile: friction along q: ``{"q", "friction", "std", "n"}`` per bin.
        radius: distance of the handle from a revolute axis, m (converts a torque into the
            force at the handle); None for prismatic joints.
        q_offset, q_sign: the opening in the link model's own coordinate q_link:
            opening = q_sign * (q_link - q_offset) (the exported joint's coordinate is
            q_link: its spring reference is q_offset).
        friction_velocity: the friction's regularisation speed the fit assumed
            (:func:`friction_shape`; 0: ideal Coulomb friction), rad/s or m/s.
    """

    joint: str
    damping: float = 0.0
    friction: float = 0.0
    stiffness: float = 0.0
    inertia: float = 0.0
    damping_std: float = float("inf")
    friction_std: float = float("inf")
    stiffness_std: float = float("inf")
    inertia_std: float = float("inf")
    spring_reference: float = 0.0
    noise_std: float = 0.0
    covariance: list = field(default_factory=list)
    n_samples: int = 0
    q_range: list = field(default_factory=lambda: [0.0, 0.0])
    profile: list = field(default_factory=list)
    radius: float | None = None
    q_offset: float = 0.0
    q_sign: float = 1.0
    friction_velocity: float = 0.0

    def __post_init__(self):
        dynamics_units(self.joint)
        friction_shape(0.0, self.friction_velocity)  # checks it

    @property
    def units(self) -> dict:
        return dynamics_units(self.joint)

    @property
    def spring_found(self) -> bool:
        """A closing spring is found when its stiffness is more than three deviations
        above 0 and, at the largest opening seen, it pulls back with more than a quarter of
        the Coulomb friction (or 0.1 N m / 0.5 N, whichever is larger): a spring that small
        is not told from the model's own error."""
        floor = 0.1 if self.joint == "revolute" else 0.5
        pull = self.stiffness * (self.q_range[1] - self.spring_reference)
        return (self.stiffness > 3 * self.stiffness_std
                and pull > max(0.25 * abs(self.friction), floor))

    def _handle_scale(self) -> float:
        """Generalised force -> force at the handle (1/r for a revolute joint)."""
        return 1.0 / self.radius if self.joint == "revolute" and self.radius else 1.0

    def friction_at(self, q) -> np.ndarray:
        """Coulomb friction at openings q: the profile's bin (where it has samples), else
        the global estimate."""
        q = np.atleast_1d(np.asarray(q, float))
        out = np.full(q.shape, self.friction)
        good = [b for b in self.profile if b["n"] >= 5]
        if len(good) >= 2:
            qs = np.array([b["q"] for b in good])
            fs = np.array([b["friction"] for b in good])
            inside = (q >= self.q_range[0]) & (q <= self.q_range[1])
            out[inside] = np.interp(q[inside], qs, fs)
        return out

    def predict(self, q, qdot, qddot=0.0) -> tuple[np.ndarray, np.ndarray]:
        """Generalised force (mean, standard deviation) needed at openings q moving at
        rates qdot (and accelerations qddot); the deviation includes the residual noise."""
        q, qdot, qddot = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, float))
                                               for v in (q, qdot, qddot)))
        shape = friction_shape(qdot, self.friction_velocity)
        X = np.stack([qdot, shape, q - self.spring_reference, qddot], axis=-1)
        mean = (self.damping * qdot + self.friction_at(q) * shape
                + self.stiffness * (q - self.spring_reference) + self.inertia * qddot)
        C = np.asarray(self.covariance, float) if self.covariance else np.zeros((4, 4))
        var = np.einsum("...i,ij,...j->...", X, C, X) + self.noise_std ** 2
        return mean, np.sqrt(np.maximum(var, 0.0))

    def force_to_open(self, q_from: float, q_to: float, rate: float, n: int = 50) -> dict:
        """The force still needed to open from ``q_from`` to ``q_to`` at a steady ``rate``
        (rad/s or m/s): the largest and the mean generalised force over the way, with the
        deviation at the largest, the work (J), and the largest force at the handle (N)."""
        if not q_to > q_from:
            return {"from": q_from, "to": q_to, "peak": 0.0, "peak_std": 0.0, "mean": 0.0,
                    "work_J": 0.0, "peak_handle_force_N": 0.0}
        qs = np.linspace(q_from, q_to, n)
        m, s = self.predict(qs, rate)
        i = int(np.argmax(m))
        work = float(np.sum(0.5 * (m[1:] + m[:-1]) * np.diff(qs)))
        return {"from": float(q_from), "to": float(q_to), "peak": float(m[i]),
                "peak_std": float(s[i]), "mean": float(np.mean(m)), "work_J": work,
                "peak_handle_force_N": float(m[i] * self._handle_scale())}

    def to_dict(self) -> dict:
        """Plain dict (the ``dynamics`` section of a saved model)."""
        return {"joint": self.joint, "units": self.units,
                **{k: float(getattr(self, k)) for k in COEFFICIENTS},
                **{f"{k}_std": float(getattr(self, f"{k}_std")) for k in COEFFICIENTS},
                "spring_reference": float(self.spring_reference),
                "noise_std": float(self.noise_std),
                "covariance": [[float(x) for x in row] for row in self.covariance],
                "n_samples": int(self.n_samples),
                "q_range": [float(x) for x in self.q_range],
                "profile": [{k: (int(v) if k == "n" else float(v)) for k, v in b.items()}
                            for b in self.profile],
                "radius": None if self.radius is None else float(self.radius),
                "q_offset": float(self.q_offset), "q_sign": float(self.q_sign),
                "friction_velocity": float(self.friction_velocity),
                "spring_found": bool(self.spring_found)}

    @classmethod
    def from_dict(cls, d: dict) -> "MechanismDynamics":
        """Inverse of :meth:`to_dict`; raises ValueError naming a missing or bad entry."""
        if not isinstance(d, dict):
            raise ValueError("dynamics: expected a mapping")
        kw = {}
        for k in ("joint", *COEFFICIENTS, *(f"{c}_std" for c in COEFFICIENTS)):
            if k not in d:
                raise ValueError(f"dynamics: missing key {k!r}")
            kw[k] = d[k]
        for k in COEFFICIENTS:
            if not isinstance(d[k], (int, float)) or isinstance(d[k], bool) \
                    or not math.isfinite(d[k]):
                raise ValueError(f"dynamics.{k}: expected a finite number, got {d[k]!r}")
        for k in ("spring_reference", "noise_std", "covariance", "n_samples", "q_range",
                  # spring_found is derived, not stored
                  "profile", "radius", "q_offset", "q_sign", "friction_velocity"):
            if k in d:
                kw[k] = d[k]
        cov = kw.get("covariance", [])
        if cov and np.asarray(cov, float).shape != (4, 4):
            raise ValueError("dynamics.covariance: expected a 4 x 4 matrix")
        return cls(**kw)


def local_derivatives(t, q, half_window: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Rate and acceleration of q(t) at every sample from a quadratic fitted to the samples
    within ``half_window`` seconds (NaN where fewer than 5 samples are near)."""
    t, q = np.asarray(t, float), np.asarray(q, float)
    qd, qdd = np.full(t.shape, np.nan), np.full(t.shape, np.nan)
    for i, ti in enumerate(t):
        m = np.abs(t - ti) <= half_window
        if m.sum() < 5:
            continue
        c = np.polyfit(t[m] - ti, q[m], 2)
        qd[i], qdd[i] = c[1], 2 * c[0]
    return qd, qdd


def local_state(t, q, shift=0.0, half_window: float = 0.2) -> tuple[np.ndarray, ...]:
    """q, its rate and its acceleration at the times t + ``shift`` (s; a number or one
    per sample, within the samples' span): the rate and acceleration of
    :func:`local_derivatives` at the samples, each of the three interpolated linearly to
    the shifted times (NaN where a neighbour's is)."""
    t, q = np.asarray(t, float), np.asarray(q, float)
    at = t + np.broadcast_to(np.asarray(shift, float), t.shape)
    qd, qdd = local_derivatives(t, q, half_window)
    return tuple(np.interp(at, t, x) for x in (q, qd, qdd))


def generalized_samples(link, t, G, F, *, force_lag=0.0,
                        half_window: float = 0.2) -> dict | None:
    """The mechanism's configuration, rate, acceleration and the generalised force the
    robot applies along it, from hook positions G (k, 3) and wrist forces F (k, 3, force of
    the mechanism on the hook) at times t, by the learned link model. The configuration is
    the opening: it grows along the pull and starts at 0 at the first sample.
    ``force_lag``: how much older each force reading is than its hook position (s; a
    number or one per sample): the configuration, rate and acceleration are then taken at
    the force's time (from the local quadratic fits of q(t)). For a revolute model the
    result also has ``across``: the force across the mechanism (along the learned outward
    radius, away from the axis) times the learned radius, N m: a tangent turned by a small
    angle e from the true one adds about e times it to the torque. ``half_window``: of the
    local fits (:func:`local_derivatives`), s. None when the model is not revolute or
    prismatic or there are fewer than 10 samples."""
    if link is None or getattr(link, "name", "") not in ("revolute", "prismatic"):
        return None
    t, G, F = (np.asarray(a, float) for a in (t, G, F))
    lag = np.broadcast_to(np.asarray(force_lag, float), t.shape)
    ok = np.all(np.isfinite(G), axis=1) & np.all(np.isfinite(F), axis=1) & np.isfinite(lag)
    t, G, F, lag = t[ok], G[ok], F[ok], lag[ok]
    if t.size < 10:
        return None
    q = np.asarray(link.inverse(G), float)[:, 0]
    if link.name == "revolute":
        q = np.unwrap(q)
    sign = 1.0
    if q[-1] < q[0]:  # the model's coordinate runs against the opening
        sign = -1.0
    offset = float(q[0])
    if np.any(lag != 0):
        q_raw, qd, qdd = local_state(t, q, -lag, half_window)
        q_raw = np.where(np.isfinite(q_raw), q_raw, q)
    else:
        q_raw = q
        qd, qdd = local_derivatives(t, q, half_window)
    J = np.asarray(link.jacobian(q_raw[:, None]), float)[:, :3, 0]
    tau = -np.sum(F * J, axis=1)
    q, tau, qd, qdd = sign * (q_raw - offset), sign * tau, sign * qd, sign * qdd
    out = {"joint": link.name, "t": t, "q": q, "qdot": qd, "qddot": qdd, "tau": tau,
           "radius": None, "q_offset": offset, "q_sign": sign}
    if link.name == "revolute":
        out["radius"] = float(np.median(np.linalg.norm(J, axis=1)))
        h = 1e-3
        outward = -(np.asarray(link.jacobian(q_raw[:, None] + h), float)[:, :3, 0]
                    - np.asarray(link.jacobian(q_raw[:, None] - h), float)[:, :3, 0]) / (2 * h)
        r = np.maximum(np.linalg.norm(outward, axis=1), 1e-9)
        out["across"] = -np.sum(F * outward / r[:, None], axis=1) * r
    return out


def fit_dynamics(q, qdot, tau, qddot=None, *, joint: str, min_rate: float | None = None,
                 prior_std=None, bins: int = 5, rejection_rounds: int = 2,
                 radius: float | None = None, q_offset: float = 0.0,
                 q_sign: float = 1.0,
                 friction_velocity: float = 0.0, nuisance=None,
                 nuisance_std: float = 1.0) -> MechanismDynamics | None:
    """Bayesian linear regression of the generalised force on (qdot, sign(qdot), q, qddot)
    (see the module docstring). ``min_rate``: samples slower than this, or than a quarter
    of the median rate, are left out (default 0.02 rad/s or 0.008 m/s); ``prior_std``: the coefficients' prior standard
    deviations (default: broad, by joint); ``bins``: bins of the friction profile;
    ``friction_velocity``: the friction's regularisation speed (:func:`friction_shape`;
    0: ideal Coulomb friction, sign(qdot)). ``nuisance``: further regressors (k, m), in the
    generalised force's unit per unit coefficient, fitted beside the four with zero-mean
    Gaussian priors of deviation ``nuisance_std`` and marginalised out (the result's
    coefficients, deviations and covariance are the four's; the friction profile removes
    them too): a known disturbance of unknown size, such as the force across a door that
    leaks into the torque through the learned tangent's direction error. Returns None with
    fewer than 8 usable samples."""
    dynamics_units(joint)  # checks joint
    q, qdot, tau = (np.asarray(a, float) for a in (q, qdot, tau))
    qddot = np.zeros_like(q) if qddot is None else np.asarray(qddot, float)
    rate = min_rate if min_rate is not None else (0.02 if joint == "revolute" else 0.008)
    finite = np.isfinite(q) & np.isfinite(qdot) & np.isfinite(tau) & np.isfinite(qddot)
    if finite.sum() < 8:
        return None
    # moving: faster than min_rate and than a quarter of the typical rate (the pull's
    # start and its end, at a stop, are left out)
    typical = float(np.median(np.abs(qdot[finite])))
    use = finite & (np.abs(qdot) > max(rate, 0.25 * typical))
    if use.sum() < 8:
        return None
    shape = friction_shape(qdot, friction_velocity)
    X_all = np.stack([qdot, shape, q, qddot], axis=1)
    prior = list(prior_std or _PRIOR_STD[joint])
    if nuisance is not None:
        extra = np.asarray(nuisance, float).reshape(q.size, -1)
        if not (nuisance_std > 0 and math.isfinite(nuisance_std)):
            raise ValueError(f"nuisance_std must be a finite number > 0, got {nuisance_std!r}")
        use &= np.all(np.isfinite(extra), axis=1)
        if use.sum() < 8:
            return None
        X_all = np.hstack([X_all, np.where(np.isfinite(extra), extra, 0.0)])
        prior += [nuisance_std] * extra.shape[1]
    P = np.diag(1.0 / np.square(np.asarray(prior, float)))

    def posterior(m, weights, s2):
        X, y = X_all[m] * weights[:, None], tau[m] * weights
        cov = np.linalg.inv(X.T @ X / s2 + P)
        return cov @ (X.T @ y) / s2, cov

    # robust start (Huber weights, scale by the median absolute residual): a hook that
    # slips or the end stop gives forces far off the model
    wts = np.ones(int(use.sum()))
    s2 = max(float(np.var(tau[use])), 1e-8)
    for _ in range(8):
        w, cov = posterior(use, wts, s2)
        r = tau[use] - X_all[use] @ w
        scale = max(1.4826 * float(np.median(np.abs(r))), 1e-6)
        wts = np.sqrt(np.minimum(1.0, 1.5 * scale / np.maximum(np.abs(r), 1e-12)))
        s2 = scale ** 2
    keep = use.copy()
    for _ in range(rejection_rounds + 1):
        res = np.abs(tau - X_all @ w)
        new = use & (res < 3.0 * math.sqrt(s2))
        if new.sum() < 8:
            break
        keep = new
        # noise by empirical Bayes: the residual variance at the posterior mean
        for _ in range(2):
            w, cov = posterior(keep, np.ones(int(keep.sum())), s2)
            s2 = max(float(np.mean((tau[keep] - X_all[keep] @ w) ** 2)), 1e-8)
        w, cov = posterior(keep, np.ones(int(keep.sum())), s2)
    cov = cov[:4, :4]   # the nuisance terms marginalised out
    sd = np.sqrt(np.diag(cov))
    qk = q[keep]
    profile = []
    if bins >= 1 and qk.size:
        edges = np.linspace(qk.min(), qk.max(), bins + 1)
        # per bin the friction f_bin that fits the residual best: resid ~ f_bin s(qdot)
        others = [0, 2, 3, *range(4, w.size)]
        resid = tau - X_all[:, others] @ w[others]
        for a, b in zip(edges[:-1], edges[1:]):
            m = keep & (q >= a) & (q <= b)
            ss = float(np.sum(shape[m] ** 2))
            if m.sum() and ss > 0:
                f_bin = float(np.sum(resid[m] * shape[m]) / ss)
                spread = float(np.std(resid[m] - f_bin * shape[m]))
                profile.append({"q": float(0.5 * (a + b)), "friction": f_bin,
                                "std": spread / math.sqrt(ss), "n": int(m.sum())})
    return MechanismDynamics(
        joint=joint, damping=float(w[0]), friction=float(w[1]), stiffness=float(w[2]),
        inertia=float(w[3]), damping_std=float(sd[0]), friction_std=float(sd[1]),
        stiffness_std=float(sd[2]), inertia_std=float(sd[3]), spring_reference=0.0,
        noise_std=math.sqrt(s2), covariance=cov.tolist(), n_samples=int(keep.sum()),
        q_range=[float(qk.min()), float(qk.max())], profile=profile, radius=radius,
        q_offset=float(q_offset), q_sign=float(q_sign),
        friction_velocity=float(friction_velocity))


# ---------------------------------------------------------------------- storage and export
def save_model_with_dynamics(model, dynamics: MechanismDynamics | None, path) -> None:
    """Save a learned model (:func:`mmlearn.models.articulation.io.save_model`'s formats,
    by extension: .json, .yaml, .yml) with its dynamics as the optional top-level section
    ``dynamics`` (``{"edge": 0, ...}``: the dynamics of the model's first link)."""
    from mmlearn.models.articulation.io import model_to_dict, write_model_document
    from mmlearn.models.common.saved_doc import seal

    d = model_to_dict(model)
    if dynamics is not None:
        d["dynamics"] = {"edge": 0, **dynamics.to_dict()}
        d = seal(d)     # the checksum covers the dynamics too
    write_model_document(d, path)


def load_model_with_dynamics(path):
    """Load a model saved by :func:`save_model_with_dynamics` (or by ``save_model``): the
    model and its :class:`MechanismDynamics` (None when the file has none). Raises
    ValueError naming the file and the problem."""
    from mmlearn.models.articulation.io import read_model_document

    model, d = read_model_document(path)
    p = Path(path)
    if d.get("dynamics") is None:
        return model, None
    try:
        return model, MechanismDynamics.from_dict(d["dynamics"])
    except (ValueError, TypeError) as e:
        raise ValueError(f"{p}: {e}") from None


def sdf_with_dynamics(model, dynamics: MechanismDynamics | None, *,
                      model_name: str = "learned_object") -> str:
    """The learned model as SDFormat (:func:`mmlearn.models.articulation.io.to_sdf`) with
    the dynamics in its first joint's ``<axis><dynamics>``: damping, friction, and the
    spring (reference and stiffness) where one was found
    (:attr:`MechanismDynamics.spring_found`). Negative estimates are written as 0 (SDFormat needs
    non-negative damping and friction)."""
    from mmlearn.models.articulation.io import to_sdf

    text = to_sdf(model, model_name=model_name)
    if dynamics is None:
        return text
    root = ET.fromstring(text)
    joints = [j for j in root.iter("joint") if j.get("type") == dynamics.joint]
    if not joints:
        raise ValueError(f"the model has no {dynamics.joint} joint for its dynamics")
    axis = joints[0].find("axis")
    dyn = axis.find("dynamics")
    if dyn is None:
        dyn = ET.SubElement(axis, "dynamics")
    values = {"damping": max(dynamics.damping, 0.0), "friction": max(dynamics.friction, 0.0)}
    if dynamics.spring_found:
        # the spring pulls towards the closed configuration, where the pull began: in
        # the exported joint's (the link model's) coordinate
        values["spring_reference"] = dynamics.q_offset + dynamics.q_sign * \
            dynamics.spring_reference
        values["spring_stiffness"] = dynamics.stiffness
    for k, v in values.items():
        e = dyn.find(k)
        if e is None:
            e = ET.SubElement(dyn, k)
        e.text = repr(float(v))
    ET.indent(root, "  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def path_opening(P, joint: str, *, radius_prior: tuple = (0.40, 0.12),
                 sigma: float = 0.01) -> float:
    """How far a handle moved along its path P (k, 3; m): for a ``"prismatic"`` mechanism
    the distance from the first to the last point (m); for a ``"revolute"`` one the angle
    its path turned (rad), from a circle fitted in the path's plane with a Gaussian prior
    on the radius (``radius_prior``: mean and deviation, m; the handle radius of kitchen
    cabinet doors 0.3-0.6 m wide) against points of deviation ``sigma`` (m; the drift of the robot's
    localisation over a pull). Model free: usable before the learned model is the right
    kind (a short arc reads as a line at the estimator's noise)."""
    from scipy.optimize import least_squares

    P = np.asarray(P, float)
    P = P[np.all(np.isfinite(P), axis=1)]
    if P.shape[0] < 2:
        return 0.0
    if joint == "prismatic":
        return float(np.linalg.norm(P[-1] - P[0]))
    if joint != "revolute":
        raise ValueError(f"joint must be revolute or prismatic, got {joint!r}")
    if P.shape[0] < 5:
        return 0.0
    c = P.mean(axis=0)
    _, _, Vt = np.linalg.svd(P - c)
    xy = (P - c) @ Vt[:2].T
    r0, sr = radius_prior
    chord = xy[-1] - xy[0]
    L = float(np.linalg.norm(chord))
    if L < 1e-6:
        return 0.0
    mid = 0.5 * (xy[-1] + xy[0])
    perp = np.array([-chord[1], chord[0]]) / L

    def res(x):
        return np.concatenate([(np.linalg.norm(xy - x[:2], axis=1) - x[2]) / sigma,
                               [(x[2] - r0) / sr]])

    best = None
    for side in (1.0, -1.0):
        h = math.sqrt(max(r0 ** 2 - (L / 2) ** 2, 1e-4))
        x0 = np.array([*(mid + side * h * perp), r0])
        sol = least_squares(res, x0)
        if best is None or sol.cost < best.cost:
            best = sol
    centre = best.x[:2]
    a0, a1 = xy[0] - centre, xy[-1] - centre
    return abs(math.atan2(a0[0] * a1[1] - a0[1] * a1[0], float(a0 @ a1)))
