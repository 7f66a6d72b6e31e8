"""LearnedModelVisualizer: draws the currently learned articulation model in Meshcat, with
a legend that says what the drawn lines mean."""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.geometry import Mesh, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import EventStatus, LeafSystem

_AXIS = Rgba(0.1, 0.4, 1.0, 1.0)
_RANGE = Rgba(1.0, 0.15, 0.1, 1.0)
_FAINT = Rgba(0.1, 0.4, 1.0, 0.5)

#: Meshcat path of the legend: a child of the default camera, so it stays in the top-left
#: corner of the view however the user orbits or zooms (Meshcat adds the objects under a
#: path to the three.js object of its parent; the camera is /Cameras/default/rotated/<object>).
LEGEND_PATH = "/Cameras/default/rotated/<object>/legend"

# the legend image: pixels per row, width; its size in the camera frame (three.js: x right,
# y up, looking along -z): drawn _LEGEND_DEPTH in front of the camera, the rows
# _LEGEND_ROW high, the top-left corner at (_LEGEND_LEFT, _LEGEND_TOP). Meshcat's default
# camera has a 75 deg vertical field of view: at 0.1 m the view is +-0.077 m high and, in
# a 4:3 or wider window, at least +-0.102 m wide; the left edge at -0.078 keeps clear of
# the real-time-rate panel (80 px) of Drake's live page in windows from 800 px wide.
_ROW_PX, _WIDTH_PX = 40, 620
_LEGEND_DEPTH, _LEGEND_ROW = 0.1, 0.0052
_LEGEND_LEFT, _LEGEND_TOP = -0.078, 0.0735


def legend_entries(link) -> tuple[str, list[tuple[Rgba | None, str, str]]]:
    """The legend of what ``LearnedModelVisualizer.draw(link)`` draws: a title and rows
    ``(colour, "line" | "thin" | "dot", text)`` in the colours of the drawing (colour None:
    a row of text only)."""
    if link is None:
        return "Learned model: none yet", [
            (None, "", "appears once the hook has moved the handle")]
    name = link.name
    lo = float(link.q_min[0]) if getattr(link, "dof", 0) else 0.0
    hi = float(link.q_max[0]) if getattr(link, "dof", 0) else 0.0
    if name == "revolute":
        return "Learned model: revolute", [
            (_AXIS, "line", "learned rotation axis"),
            (_FAINT, "thin", f"learned circle (radius {float(link.radius):.2f} m)"),
            (_AXIS, "dot", "circle centre (on the axis)"),
            (_RANGE, "line", f"observed opening range ({math.degrees(hi - lo):.0f} deg)")]
    if name == "prismatic":
        return "Learned model: prismatic", [
            (_FAINT, "thin", "learned prismatic axis"),
            (_RANGE, "line", f"observed opening range ({hi - lo:.2f} m)")]
    if name == "rigid":
        return "Learned model: rigid", [
            (_RANGE, "dot", "fixed handle position (no motion seen)")]
    return f"Learned model: {name}", [(_RANGE, "dot", "model position at q = 0")]


def _font(size: int, bold: bool = False):
    """DejaVu Sans from matplotlib's data (a dependency), else Pillow's own font."""
    from PIL import ImageFont

    try:
        import matplotlib

        name = "DejaVuSans-Bold.ttf" if bold else "DejaVuSans.ttf"
        ttf = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / name
        return ImageFont.truetype(str(ttf), size)
    except (ImportError, OSError):
        return ImageFont.load_default(size=size)


def _legend_png(path: Path, title: str, rows) -> tuple[int, int]:
    from PIL import Image, ImageDraw  # Pillow comes with matplotlib

    W, H = _WIDTH_PX, _ROW_PX * (len(rows) + 1) + 12
    img = Image.new("RGB", (W, H), (250, 250, 250))
    d = ImageDraw.Draw(img)
    font_title, font = _font(int(0.6 * _ROW_PX), bold=True), _font(int(0.55 * _ROW_PX))
    d.rectangle([0, 0, W - 1, H - 1], outline=(90, 90, 90), width=2)
    d.text((12, 6 + _ROW_PX // 2), title, fill=(0, 0, 0), font=font_title, anchor="lm")
    for i, (c, kind, text) in enumerate(rows):
        y = 6 + _ROW_PX * (i + 1) + _ROW_PX // 2
        if c is None:
            d.text((14, y), text, fill=(60, 60, 60), font=font, anchor="lm")
            continue
        # a translucent line's colour as it looks over the grey floor
        rgb = tuple(int(round(255 * (c.a() * v + 0.6 * (1 - c.a()))))
                    for v in (c.r(), c.g(), c.b()))
        if kind == "dot":
            d.ellipse([34, y - 8, 50, y + 8], fill=rgb)
        else:
            d.line([(14, y), (70, y)], fill=rgb, width=8 if kind == "line" else 3)
        d.text((84, y), text, fill=(0, 0, 0), font=font, anchor="lm")
    img.save(path)
    return W, H


def draw_legend(meshcat, title: str, rows, *, path: str = LEGEND_PATH) -> None:
    """Draw a legend panel (``title`` and rows as ``legend_entries`` makes them) at
    ``path``; under the default ``LEGEND_PATH`` it is fixed to the top-left corner of the
    view, live and in a recording's standalone HTML. The panel is a textured quad (an OBJ
    with an emissive PNG texture, so the scene's lights do not dim it)."""
    with tempfile.TemporaryDirectory(prefix="mmlearn_legend_") as tmp:
        tmp = Path(tmp)
        W, H = _legend_png(tmp / "legend.png", title, rows)
        h = _LEGEND_ROW * H / _ROW_PX
        w = h * W / H
        (tmp / "legend.mtl").write_text(
            "newmtl legend\nKa 0 0 0\nKd 0 0 0\nKs 0 0 0\nKe 1 1 1\n"
            "map_Ke legend.png\n")
        # the legend's text also as comments of the OBJ (embedded in a recording's HTML)
        (tmp / "legend.obj").write_text(
            f"# mmlearn legend: {title}\n"
            + "".join(f"# {text}\n" for _, _, text in rows)
            + "mtllib legend.mtl\n"
            f"v 0 {-h} 0\nv {w} {-h} 0\nv {w} 0 0\nv 0 0 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl legend\n"
            "f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n")
        meshcat.SetObject(path, Mesh(str(tmp / "legend.obj")))
    meshcat.SetTransform(path, RigidTransform([_LEGEND_LEFT, _LEGEND_TOP, -_LEGEND_DEPTH]))


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
