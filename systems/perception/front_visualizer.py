"""FrontTrackVisualizer: draws detected cabinet-front rectangles, the FrontTracker's tracks
and their learned link models in Meshcat (thesis ch. 5; the point cloud is drawn by Drake's
own MeshcatPointCloudVisualizer)."""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Rgba
from pydrake.systems.framework import EventStatus, LeafSystem

from mmlearn.models.perception.tracking import as_rectangle

from mmlearn.systems.articulation.model_visualizer import draw_link_model

__all__ = ["FrontTrackVisualizer", "front_legend", "track_colour"]

_DETECTION = Rgba(0.45, 0.45, 0.45, 1.0)
_PALETTE = [(0.1, 0.7, 0.2), (1.0, 0.6, 0.0), (0.6, 0.2, 0.9), (0.0, 0.7, 0.8),
            (0.9, 0.2, 0.5), (0.5, 0.5, 0.1)]


def track_colour(track_id: int) -> Rgba:
    """The colour of a track (by its id, cycling through 6 colours)."""
    r, g, b = _PALETTE[int(track_id) % len(_PALETTE)]
    return Rgba(r, g, b, 1.0)


def _loop(rect) -> np.ndarray:
    c = rect.corners()
    return np.vstack([c, c[:1]]).T  # (3, 5) closed outline


class FrontTrackVisualizer(LeafSystem):
    """Shows the current frame's rectangles (grey outlines), each published track (its
    latest rectangle outlined and the path of its centre, in the track's colour) and each
    track's learned link model (models/model_visualizer.draw_link_model: revolute axis and
    opening arc, prismatic axis and range) in Meshcat, under ``prefix``.

    Redrawn from the inputs by a periodic publish every ``period`` seconds and on a forced
    publish; no state (what is drawn is a function of the inputs and the time). Unconnected
    inputs draw nothing; a drawing error never stops the simulation.

    With ``recording`` (the scene's recording getter, ``MeshcatVisualizer.
    get_mutable_recording`` - the bound method, called at each publish: a reference taken
    before ``StartRecording`` can dangle, seen as a crash in a 30 Hz camera run - or a
    ``MeshcatAnimation`` the caller keeps alive), every
    publish draws into its own group ``<prefix>/frames/<k>`` (k = floor(time / period))
    instead of replacing one drawing, and keys the group's ``visible`` property into the
    animation: hidden from its start, shown at its time, hidden again at the next group's
    time. So the recording (``--html-out``) plays each camera frame's rectangles, tracks and
    models at their time, not only the final state; live, the previous group is hidden.

    .. pydrake_system::

        name: FrontTrackVisualizer
        input_ports:
        - rectangles
        - tracks
        - models
    """

    def __init__(self, *, meshcat, period: float = 0.1, prefix: str = "fronts",
                 recording=None):
        """Args: meshcat: the Meshcat instance; period: publish period, s; prefix: Meshcat
        path of the drawings; recording: None or a ``MeshcatAnimation`` (anything with
        ``frame(time)`` and ``SetProperty(frame, path, property, bool)``), or a callable
        without arguments returning one at each publish, to key each frame's drawing into
        (see the class docstring)."""
        super().__init__()
        if not period > 0:
            raise ValueError(f"period must be > 0 s, got {period}")
        if recording is not None and hasattr(recording, "frame") \
                and hasattr(recording, "SetProperty"):
            anim = recording
            recording = lambda: anim  # noqa: E731 - one getter for both forms
        elif recording is not None and not callable(recording):
            raise ValueError("recording must be a MeshcatAnimation (frame(), SetProperty()) "
                             "or a callable returning one, got "
                             f"{type(recording).__name__}")
        self._meshcat, self._prefix = meshcat, str(prefix)
        # None, or the getter of the animation (called at each publish)
        self._period, self._recording = float(period), recording
        self._rects = self.DeclareAbstractInputPort("rectangles", AbstractValue.Make(list()))
        self._tracks = self.DeclareAbstractInputPort("tracks", AbstractValue.Make(tuple()))
        self._models = self.DeclareAbstractInputPort("models", AbstractValue.Make(dict()))
        self.DeclarePeriodicPublishEvent(period, 0.0, self._publish)
        self.DeclareForcedPublishEvent(self._publish)

    def get_rectangles_input_port(self):
        """The current frame's rectangles (list[FrontRectangle])."""
        return self._rects

    def get_tracks_input_port(self):
        """FrontTracker's ``tracks`` output."""
        return self._tracks

    def get_models_input_port(self):
        """FrontTracker's ``models`` output."""
        return self._models

    @staticmethod
    def _value(port, context, default):
        try:
            return port.Eval(context) if port.HasValue(context) else default
        except Exception:  # noqa: BLE001 - a bad input draws nothing
            return default

    def _publish(self, context):
        rects = self._value(self._rects, context, [])
        tracks = self._value(self._tracks, context, ())
        models = self._value(self._models, context, {})
        try:
            if self._recording is None:
                self.draw(rects, tracks, models)
            else:
                self._draw_recorded(context.get_time(), rects, tracks, models)
        except (RuntimeError, ValueError, TypeError, AttributeError, IndexError):
            return EventStatus.DidNothing()  # a drawing never stops the simulation
        return EventStatus.Succeeded()

    def frame_group(self, time: float) -> str:
        """Meshcat path of the drawing of the publish at ``time`` (s) with a recording."""
        return f"{self._prefix}/frames/{int(math.floor(time / self._period + 1e-6))}"

    def _draw_recorded(self, t, rectangles, tracks, models) -> None:
        mc, anim = self._meshcat, self._recording()  # the recording as it is now
        k = int(math.floor(t / self._period + 1e-6))
        group = f"{self._prefix}/frames/{k}"
        prev = f"{self._prefix}/frames/{k - 1}"
        self.draw(rectangles, tracks, models, prefix=group)
        f = int(anim.frame(t))
        if f > 0:
            anim.SetProperty(0, group, "visible", False)
        anim.SetProperty(f, group, "visible", True)
        mc.SetProperty(group, "visible", True)
        if k > 0 and mc.HasPath(prev):
            anim.SetProperty(f, prev, "visible", False)
            mc.SetProperty(prev, "visible", False)

    def draw(self, rectangles, tracks, models, *, prefix: str | None = None) -> None:
        """Draw one frame's rectangles, the tracks and their models under ``prefix`` (default:
        the visualizer's), replacing what was drawn there."""
        mc, pre = self._meshcat, self._prefix if prefix is None else prefix
        mc.Delete(f"{pre}/detections")
        items = rectangles if isinstance(rectangles, (list, tuple)) else []
        for i, r in enumerate(x for x in (as_rectangle(y) for y in items) if x is not None):
            mc.SetLine(f"{pre}/detections/{i}", _loop(r), 2.0, _DETECTION)
        mc.Delete(f"{pre}/tracks")
        for t in tracks if isinstance(tracks, (list, tuple)) else ():
            col = track_colour(t.track_id)
            path = f"{pre}/tracks/{t.track_id}"
            mc.SetLine(f"{path}/rectangle", _loop(t.rectangle(-1)), 4.0, col)
            if t.n >= 2:
                mc.SetLine(f"{path}/centres", np.asarray(t.poses[:, :3]).T, 1.5, col)
            m = models.get(t.track_id) if isinstance(models, dict) else None
            if m is not None:
                draw_link_model(mc, f"{path}/model", m.model)


def front_legend(object_name: str, moving_track_id, tracks, models, *,
                 point_cloud: bool = True) -> tuple[str, list]:
    """The legend of a front-perception recording (``draw_legend``'s title and rows): what
    ``FrontTrackVisualizer`` draws, in its colours, with the learned model of the moving
    front's track (``moving_track_id``; None when no track matched the front) and its
    numbers, the other tracks' models counted by kind, and the depth camera and its cloud
    (drawn by the perception diagram). ``tracks``, ``models``: the FrontTracker's outputs at
    the end of the run."""
    from mmlearn.systems.articulation.model_visualizer import _AXIS, _FAINT, _RANGE

    by_id = {t.track_id: t for t in tracks if hasattr(t, "track_id")}
    rows = []
    m = models.get(moving_track_id) if moving_track_id is not None else None
    link = getattr(m, "model", None)
    if moving_track_id is not None and moving_track_id in by_id:
        t = by_id[moving_track_id]
        what = "no model yet" if link is None else f"learned {link.name}"
        if link is not None and link.name == "revolute":
            what += f", radius {float(link.radius):.2f} m"
        rows.append((track_colour(moving_track_id), "line",
                     f"moving {object_name}'s track {moving_track_id} ({t.n} detections): "
                     f"{what}"))
        if link is not None and link.name == "revolute":
            span = math.degrees(float(link.q_max[0] - link.q_min[0]))
            rows += [(_AXIS, "line", "  its learned rotation axis"),
                     (_RANGE, "line", f"  span of its track on the model ({span:.0f} deg)")]
        elif link is not None and link.name == "prismatic":
            span = float(link.q_max[0] - link.q_min[0])
            rows += [(_FAINT, "thin", "  its learned prismatic axis"),
                     (_RANGE, "line", f"  span of its track on the model ({span:.2f} m)")]
    else:
        rows.append((None, "", f"the moving {object_name} was not tracked"))
    others = [k for k in by_id if k != moving_track_id]
    kinds: dict[str, int] = {}
    for k in others:
        name = getattr(getattr(models.get(k), "model", None), "name", "no model")
        kinds[name] = kinds.get(name, 0) + 1
    if others:
        counts = ", ".join(f"{n} {kind}" for kind, n in sorted(kinds.items()))
        rows.append((track_colour(others[0]), "thin",
                     f"{len(others)} other tracks (one colour each; learned: {counts})"))
    if kinds.get("rigid"):
        rows.append((_RANGE, "dot", "  fixed position of a track learned rigid"))
    rows += [(_DETECTION, "thin", "rectangles detected in the frame shown"),
             (Rgba(0.1, 0.1, 0.8, 1.0), "thin", "depth camera (black box) and its view")]
    if point_cloud:
        rows.append((Rgba(0.7, 0.7, 0.7, 1.0), "dots", "noisy depth points of that frame"))
    return "Front perception: detections, tracks, learned models", rows
