"""LearnedModelVisualizer: draws the currently learned articulation model in Meshcat, with
a legend that says what the drawn lines mean."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.geometry import Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import EventStatus, LeafSystem

from mmlearn.systems.common.meshcat_view import LEGEND_PATH, draw_legend  # noqa: F401

_AXIS = Rgba(0.1, 0.4, 1.0, 1.0)
_RANGE = Rgba(1.0, 0.15, 0.1, 1.0)
_FAINT = Rgba(0.1, 0.4, 1.0, 0.5)


def legend_entries(link) -> tuple[str, list[tuple[Rgba | None, str, str]]]:
    """The legend of what ``LearnedModelVisualizer.draw(link)`` draws: a title and rows
    ``(colour, "line" | "thin" | "dot", text)`` in the colours of the drawing (colour None:
    a row of text only).

    The range row is the span of the track the model was fitted to (the configurations of
    its observations on the learned model, ``q_min`` to ``q_max``): what the estimator saw
    of the motion by its last fit, not the mechanism's true opening (which an app reports
    from the simulation; it is larger when the mechanism moved on after the last fit or
    before the hook held it)."""
    if link is None:
        return "Learned model: none yet", [
            (None, "", "appears once the hook has moved the handle")]
    name = link.name
    lo = float(link.q_min[0]) if getattr(link, "dof", 0) else 0.0
    hi = float(link.q_max[0]) if getattr(link, "dof", 0) else 0.0
    n = getattr(link, "n_train", None)
    pts = f", {int(n)} observations" if isinstance(n, (int, np.integer)) and n > 0 else ""
    if name == "revolute":
        return "Learned model: revolute", [
            (_AXIS, "line", "learned rotation axis"),
            (_FAINT, "thin", f"learned circle (radius {float(link.radius):.2f} m)"),
            (_AXIS, "dot", "circle centre (on the axis)"),
            (_RANGE, "line", f"span of the track it was fitted to "
                             f"({math.degrees(hi - lo):.0f} deg{pts})")]
    if name == "prismatic":
        return "Learned model: prismatic", [
            (_FAINT, "thin", "learned prismatic axis"),
            (_RANGE, "line", f"span of the track it was fitted to ({hi - lo:.2f} m{pts})")]
    if name == "rigid":
        return "Learned model: rigid", [
            (_RANGE, "dot", f"fixed handle position (no motion seen{pts})")]
    return f"Learned model: {name}", [(_RANGE, "dot", f"model position at q = 0{pts}")]


@dataclass(frozen=True)
class _Shown:
    """The link model on display (a reference; models are replaced, never mutated) and
    the time it changed, s. Immutable: Drake's copies share it."""

    link: object = None
    changed_at: float = -math.inf

    def __deepcopy__(self, memo):
        return self


class LearnedModelVisualizer(LeafSystem):
    """Shows the learned model of the first link of an ``ArticulatedObject`` in Meshcat.

    Revolute: the rotation axis (blue), the circle of the tracked point (faint) and the
    observed configuration range as a red arc. Prismatic: the axis (faint) and the observed
    range (red). Rigid: the fixed position. The input is checked every ``period`` seconds;
    a changed model is drawn half a period later (and on a forced publish), under
    ``prefix`` in the Meshcat tree.

    A legend (``legend_entries``) says what each line means, in the drawing's colours, with
    the learned radius and the observed range; it is drawn at ``legend_path`` (default
    ``LEGEND_PATH``: fixed to the top-left corner of the view; None: no legend) when the
    simulation is initialised ("none yet") and with every drawing.

    .. pydrake_system::

        name: LearnedModelVisualizer
        input_ports:
        - object_model
    """

    def __init__(self, *, meshcat, period: float = 0.25, prefix: str = "learned_model",
                 legend_path: str | None = LEGEND_PATH):
        super().__init__()
        if not period > 0:
            raise ValueError(f"period must be > 0, got {period}")
        self._meshcat, self._prefix, self._period = meshcat, prefix, float(period)
        self._legend_path = legend_path
        self._in = self.DeclareAbstractInputPort("object_model", AbstractValue.Make(None))
        # which model is shown lives in the context: every period an update records the
        # input's link model when it changed (and when); half a period later a publish
        # draws it if it changed at that update. A forced publish always draws.
        self._shown = self.DeclareAbstractState(AbstractValue.Make(_Shown()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        self.DeclarePeriodicPublishEvent(period, 0.5 * period, self._publish)
        self.DeclareForcedPublishEvent(self._publish_forced)
        # at initialisation: clear an old drawing, show the legend ("none yet")
        self.DeclareInitializationPublishEvent(self._publish_forced)

    def get_object_model_input_port(self):
        return self._in

    def _link(self, context):
        obj = self._in.Eval(context) if self._in.HasValue(context) else None
        return obj.edges[0].model if obj is not None and getattr(obj, "edges", None) else None

    def _update(self, context, state):
        link = self._link(context)
        if link is context.get_abstract_state(self._shown).get_value().link:
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._shown).set_value(
            _Shown(link=link, changed_at=context.get_time()))
        return EventStatus.Succeeded()

    def _publish(self, context):
        shown = context.get_abstract_state(self._shown).get_value()
        # drawn once: by the first publish after the update that changed it
        if not context.get_time() - shown.changed_at < 0.75 * self._period:
            return EventStatus.DidNothing()
        return self._publish_forced(context)

    def _publish_forced(self, context):
        try:
            self.draw(context.get_abstract_state(self._shown).get_value().link)
        except (RuntimeError, ValueError, AttributeError, OSError, ImportError):
            return EventStatus.DidNothing()  # a drawing never stops the simulation
        return EventStatus.Succeeded()

    def draw(self, link) -> None:
        """Draw one link model (None clears the drawing)."""
        self._meshcat.Delete(self._prefix)
        if link is not None:
            self._draw_model(link)
        if self._legend_path is not None:
            draw_legend(self._meshcat, *legend_entries(link), path=self._legend_path)

    def _draw_model(self, link) -> None:
        draw_link_model(self._meshcat, self._prefix, link)


def draw_link_model(meshcat, prefix: str, link) -> None:
    """Draw a fitted link model (revolute: axis, circle, centre and observed range; prismatic:
    axis and range; otherwise the fixed position) under ``prefix`` in ``meshcat``."""
    mc, pre = meshcat, prefix
    name = link.name
    if name == "revolute":
        a, c = np.asarray(link.axis), np.asarray(link.center)
        mc.SetLine(f"{pre}/axis", np.column_stack([c - 0.6 * a, c + 0.6 * a]), 3.0, _AXIS)
        # the observed range and the full circle of the tracked point, through the
        # model's forward kinematics
        lo, hi = float(link.q_min[0]), float(link.q_max[0])
        qs = np.linspace(lo, hi, 40)
        P = np.asarray(link.forward(qs[:, None]))[:, :3]
        mc.SetLine(f"{pre}/range", P.T, 6.0, _RANGE)
        ring = np.asarray(link.forward(np.linspace(-np.pi, np.pi, 90)[:, None]))[:, :3]
        mc.SetLine(f"{pre}/circle", ring.T, 1.5, _FAINT)
        mc.SetObject(f"{pre}/center", Sphere(0.015), _AXIS)
        mc.SetTransform(f"{pre}/center", RigidTransform(c))
    elif name == "prismatic":
        a = np.asarray(link.axis)
        lo, hi = float(link.q_min[0]), float(link.q_max[0])
        P = np.asarray(link.forward(np.array([[lo], [hi]])))[:, :3]
        mid = P.mean(axis=0)
        mc.SetLine(f"{pre}/axis", np.column_stack([mid - 0.8 * a, mid + 0.8 * a]), 1.5,
                   _FAINT)
        mc.SetLine(f"{pre}/range", P.T, 6.0, _RANGE)
    else:
        p = np.asarray(link.forward(np.zeros((1, link.dof)) if link.dof else None))[0, :3]
        mc.SetObject(f"{pre}/position", Sphere(0.02), _RANGE)
        mc.SetTransform(f"{pre}/position", RigidTransform(p))
