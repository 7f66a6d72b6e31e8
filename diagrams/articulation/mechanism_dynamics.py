"""The mechanism's dynamics in an opening trial: the true values written into the simulated
mechanism (damping, friction, a closing spring, a jam or a latch) and what the robot learned
of them (:class:`~mmlearn.systems.articulation.jam_monitor.DynamicsMonitor`), as the trial
record's ``dynamics`` entry, and the learned model saved with its dynamics.

Units: revolute mechanisms (doors, dishwasher) rad, N m s/rad, N m, N m/rad; prismatic ones
(drawers, sliding doors) m, N s/m, N, N/m; forces at the handle N.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from mmlearn.models.articulation.dynamics import (dynamics_units, fit_dynamics,
                                                  save_model_with_dynamics, sdf_with_dynamics)
from mmlearn.models.common.fileio import atomic_write_text

__all__ = ["LATCH_PLAY", "apply_mechanism_options", "dynamics_record", "save_learned_model",
           "MODEL_SUFFIXES"]

#: a latched mechanism moves this far (rad or m) before the latch holds it
LATCH_PLAY = 0.002
#: extensions of ``save_model``: SDFormat, or the project's model format (JSON / YAML)
MODEL_SUFFIXES = (".sdf", ".json", ".yaml", ".yml")


def apply_mechanism_options(spec, *, damping=None, friction=None, spring=None, jam_at=None,
                            locked: bool = False):
    """The mechanism ``spec`` with the given true dynamics (None: keep the drawn value):
    ``damping`` (N m s/rad or N s/m), ``friction`` (N m or N), ``spring`` (a closing spring,
    N m/rad or N/m), ``jam_at`` (a hard stop at this opening, rad or m, below the end
    stop) or ``locked`` (latched shut: it moves ``LATCH_PLAY`` at most). Raises ValueError
    naming a bad value."""
    changes = {}
    for name, v in (("damping", damping), ("friction", friction), ("spring", spring)):
        if v is not None:
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v}")
            changes[name] = float(v)
    if jam_at is not None and locked:
        raise ValueError("jam_at and locked exclude each other")
    if jam_at is not None:
        unit = "rad" if spec.is_revolute else "m"
        if not (math.isfinite(jam_at) and LATCH_PLAY < jam_at < spec.limit):
            raise ValueError(f"jam_at must lie between {LATCH_PLAY} and the end stop "
                             f"{spec.limit:.3f} {unit}, got {jam_at:.4g} {unit}")
        changes["limit"] = float(jam_at)
    if locked:
        changes["limit"] = LATCH_PLAY
    return replace(spec, **changes)


def _prediction(g, q_split, friction_velocity: float = 0.0) -> dict | None:
    """Dynamics fitted on the samples before ``q_split`` predicting the generalised force
    over the rest of the pull, against the force measured there."""
    first = g["q"] <= q_split
    rest = (g["q"] > q_split) & np.isfinite(g["qdot"]) & (g["qdot"] > 0)
    if first.sum() < 20 or rest.sum() < 10:
        return None
    dyn = fit_dynamics(g["q"][first], g["qdot"][first], g["tau"][first], g["qddot"][first],
                       joint=g["joint"], radius=g["radius"],
                       friction_velocity=friction_velocity)
    if dyn is None:
        return None
    pred, sd = dyn.predict(g["q"][rest], g["qdot"][rest], g["qddot"][rest])
    meas = g["tau"][rest]
    scale = 1.0 / g["radius"] if g["joint"] == "revolute" else 1.0
    return {"from": float(q_split), "to": float(g["q"][rest].max()),
            "predicted_mean_force": float(np.mean(pred)),
            "predicted_std": float(np.mean(sd)),
            "measured_mean_force": float(np.mean(meas)),
            "predicted_handle_force_N": float(np.mean(pred) * scale),
            "measured_handle_force_N": float(np.mean(meas) * scale)}


def dynamics_record(op, ctx, to_unit, options: dict) -> dict:
    """The record's ``dynamics`` entry and the block's fields of a simulated trial ``op``
    at its root context ``ctx``: ``jammed_at``; ``peak_force_N``, the largest wrist force
    held for 0.1 s while the hook held the handle; ``peak_force_impact_N``, the largest
    single sample, an impact's spike included; ``block_force_N``, the force held for 0.1 s
    from the block's start (at the latest 0.5 s before the halt) until 0.25 s after the
    halt (None without a halt). ``dynamics`` has the learned values
    (:meth:`MechanismDynamics.to_dict`, with ``prediction``: the force predicted for the
    second half of the pull from its first half, against the measured; all None when
    nothing was learned), ``learned`` (whether), ``units`` and ``true`` (the values
    written into the mechanism). ``to_unit`` converts an opening to the record's unit
    (deg or m); ``options`` are the trial's :func:`apply_mechanism_options`."""
    spec = op.mechanism
    jam = options.get("jam_at")
    true = {"damping": spec.damping, "friction": spec.friction,
            "stiffness": getattr(spec, "spring", 0.0),
            "jam_at": None if jam is None else to_unit(jam),
            "locked": bool(options.get("locked", False))}
    units = dynamics_units("revolute" if spec.is_revolute else "prismatic")
    empty = {k: None for k in ("damping", "damping_std", "friction", "friction_std",
                               "stiffness", "stiffness_std", "spring_found", "profile",
                               "prediction")}
    out = {"dynamics": {**empty, "learned": False, "units": units, "true": true},
           "jammed_at": None, "peak_force_N": None, "peak_force_impact_N": None,
           "block_force_N": None}
    if op.monitor is None:
        return out
    mctx = op.monitor.GetMyContextFromRoot(ctx)
    s = op.monitor.state(mctx)
    out["peak_force_N"] = s.held_peak_force()
    out["peak_force_impact_N"] = float(s.peak_force)
    if math.isfinite(s.t_halt):
        # from where the block began (at least the last 0.5 s before the halt: the rise)
        # until the arm had let go
        since = min(s.t_onset, s.t_halt - 0.5) if math.isfinite(s.t_onset) else -math.inf
        out["block_force_N"] = s.held_peak_force(since=since, until=s.t_halt + 0.25)
    if s.halt == 1:
        out["jammed_at"] = to_unit(s.blocked_at) if math.isfinite(s.blocked_at) else None
    est = op.estimator.GetMyContextFromRoot(ctx).get_abstract_state(0).get_value()
    link = est.model.edges[0].model if est.model is not None and est.model.edges else None
    cfg = op.monitor.config
    g = cfg.regression_samples(link, *op.monitor.regression_input(mctx))
    if g is None:
        return out
    # the samples up to the block (after it the hook lets go)
    if math.isfinite(s.t_halt):
        keep = g["t"] < s.t_halt - 0.1
        g = {k: (v[keep] if isinstance(v, np.ndarray) else v) for k, v in g.items()}
    fv = cfg.friction_velocity
    dyn = cfg.fit(g)
    if dyn is None:
        return out
    learned = dyn.to_dict()
    learned["prediction"] = _prediction(g, 0.5 * float(np.max(g["q"])), fv) \
        if g["q"].size else None
    out["dynamics"].update(learned, learned=True, units=units)
    out["learned_dynamics"] = dyn  # not JSON: taken out by the caller
    return out


def save_learned_model(path, obj, dynamics) -> str:
    """Write the learned model ``obj`` with its ``dynamics`` to ``path``: SDFormat for
    ``.sdf`` (:func:`~mmlearn.models.articulation.dynamics.sdf_with_dynamics`), else the
    project's model format (JSON / YAML) with the dynamics section. Returns the path."""
    suffix = Path(path).suffix.lower()
    if suffix not in MODEL_SUFFIXES:
        raise ValueError(f"{path}: use one of {', '.join(MODEL_SUFFIXES)}")
    if suffix == ".sdf":
        atomic_write_text(path, sdf_with_dynamics(obj, dynamics))
    else:
        save_model_with_dynamics(obj, dynamics, path)
    return str(path)
