"""Meshcat drawings of imitation learning (thesis Fig. 8.7): the demonstrations, the learned
task model and the reproduction.

* :func:`draw_demonstrations`: the demonstrated hand paths as lines;
* :func:`draw_task_model`: for every Cartesian constraint ``obj:<name>`` the hand positions
  it asks for over the time slices, ``x_obj - mu_k`` (in the world frame of the
  reproduction's objects), as a line, and at every ``every``-th slice its variance as a
  translucent ellipsoid with semi-axes ``n_sigma * sqrt(var_k)`` (diagonal variances; a
  full covariance is drawn by its diagonal), under ``<prefix>/<name>/ellipsoids``: one
  group per object that Meshcat's controls can hide;
* :class:`DbnVisualizer`: the reproduction's hand trail, one dot per step, live and in a
  Meshcat recording (each dot is made visible at its time in the recording).

The static drawings are plain Meshcat objects, so they appear live and in
``Meshcat.StaticHtml()`` alike.
"""

from __future__ import annotations

import numpy as np

from pydrake.geometry import Ellipsoid, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import EventStatus, LeafSystem

#: colour per constraint object (cycled); the ellipsoids are drawn with ``ELLIPSOID_ALPHA``
PALETTE = [Rgba(0.9, 0.2, 0.2, 0.25), Rgba(0.2, 0.4, 0.95, 0.25), Rgba(0.2, 0.75, 0.3, 0.25),
           Rgba(0.85, 0.6, 0.1, 0.25), Rgba(0.6, 0.2, 0.8, 0.25)]
#: opacity of the variance ellipsoids: the scene stays visible through them
ELLIPSOID_ALPHA = 0.12


def draw_demonstrations(meshcat, demos, *, prefix: str = "imitation/demonstrations",
                        rgba: Rgba = Rgba(0.3, 0.3, 0.3, 0.8)) -> int:
    """Draw each demonstration's hand path (NaN rows skipped) as a line. Returns how many
    were drawn."""
    meshcat.Delete(prefix)
    n = 0
    for i, d in enumerate(demos):
        h = np.asarray(d.hand, float)
        h = h[np.all(np.isfinite(h), axis=1)]
        if h.shape[0] < 2 or h.shape[1] != 3:
            continue
        meshcat.SetLine(f"{prefix}/demo_{i}", np.ascontiguousarray(h.T), 2.0, rgba)
        n += 1
    return n


def draw_task_model(meshcat, model, objects: dict[str, np.ndarray], *,
                    prefix: str = "imitation/model", n_sigma: float = 2.0,
                    every: int = 1, min_radius: float = 0.003) -> int:
    """Draw the learned means (a line through the slices) and the variance ellipsoids of
    every Cartesian constraint at every ``every``-th time slice (translucent, under
    ``<prefix>/<object>/ellipsoids``), placed with the objects' world positions
    ``objects`` (name -> (3,), m). Returns how many ellipsoids were drawn."""
    meshcat.Delete(prefix)
    count = 0
    for c_i, name in enumerate(c for c in model.constraints if c.startswith("obj:")):
        obj = name[4:]
        if obj not in objects:
            continue
        x = np.asarray(objects[obj], float).reshape(3)
        mean = np.asarray(model.mean[name], float)
        var = np.asarray(model.var[name], float)
        if var.ndim == 3:
            var = np.diagonal(var, axis1=1, axis2=2)
        base = PALETTE[c_i % len(PALETTE)]
        col = Rgba(base.r(), base.g(), base.b(), ELLIPSOID_ALPHA)
        solid = Rgba(base.r(), base.g(), base.b(), 0.9)
        pts = x - mean
        meshcat.SetLine(f"{prefix}/{obj}/mean", np.ascontiguousarray(pts.T), 3.0, solid)
        for k in range(0, mean.shape[0], max(int(every), 1)):
            r = np.maximum(n_sigma * np.sqrt(np.maximum(var[k], 0.0)), min_radius)
            path = f"{prefix}/{obj}/ellipsoids/slice_{k:04d}"
            meshcat.SetObject(path, Ellipsoid(*r), col)
            meshcat.SetTransform(path, RigidTransform(pts[k]))
            count += 1
    return count


class DbnVisualizer(LeafSystem):
    """Draws the reproduction's hand trail in Meshcat: one dot per ``period``.

    .. pydrake_system::

        name: DbnVisualizer
        input_ports:
        - hand

    ``hand`` is the hand (tool centre point) position in the world, m. A discrete update
    counts the dots (the count lives in the Context); the publish half a period later draws
    dot number k at the hand, visible from its time on in a recording
    (``Meshcat.StartRecording`` before simulating, ``PublishRecording`` after).
    """

    def __init__(self, *, meshcat, period: float = 0.2, prefix: str = "imitation/trail",
                 radius: float = 0.008, rgba: Rgba = Rgba(0.1, 0.1, 0.9, 1.0)):
        super().__init__()
        if not period > 0:
            raise ValueError(f"DbnVisualizer: period must be > 0, got {period}")
        self._meshcat, self._prefix = meshcat, prefix
        self._radius, self._rgba = float(radius), rgba
        self._in = self.DeclareVectorInputPort("hand", 3)
        self._count = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclarePeriodicPublishEvent(period, 0.5 * period, self._publish)
        self.DeclareInitializationPublishEvent(self._clear)

    def get_hand_input_port(self):
        return self._in

    def _clear(self, context):
        self._meshcat.Delete(self._prefix)
        return EventStatus.Succeeded()

    def _update(self, context, discrete_state):
        discrete_state.set_value(self._count,
                                 context.get_discrete_state(self._count).get_value() + 1)
        return EventStatus.Succeeded()

    def _publish(self, context):
        p = np.asarray(self._in.Eval(context), float)
        if not np.all(np.isfinite(p)):
            return EventStatus.DidNothing()
        k = int(context.get_discrete_state(self._count).GetAtIndex(0))
        path = f"{self._prefix}/dot_{k:05d}"
        self._meshcat.SetObject(path, Sphere(self._radius), self._rgba)
        self._meshcat.SetTransform(path, RigidTransform(p))
        # in a recording (the animation is used only when one is published) the dot
        # appears at its time; the live view is not affected
        anim = self._meshcat.get_mutable_recording()
        anim.SetProperty(anim.frame(0.0), path, "visible", False)
        anim.SetProperty(anim.frame(context.get_time()), path, "visible", True)
        return EventStatus.Succeeded()
