"""TaxelPadVisualizer: draws the taxel pads in Meshcat, each cell coloured by its reading."""

from __future__ import annotations

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.geometry import Box, Rgba
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

__all__ = ["TaxelPadVisualizer", "taxel_colors"]

#: the colour levels a cell is drawn in (readings as a fraction of the full scale; a cell
#: shows the nearest level's colour)
LEVELS = np.linspace(0.0, 1.0, 5)


def taxel_colors(values: np.ndarray) -> np.ndarray:
    """RGBA (n, 4) of readings in [0, 1] (NaN and out-of-range values are clipped, NaN reads
    0): dark blue (0) through green and yellow to red (1), a 'jet'-like ramp."""
    x = np.clip(np.nan_to_num(np.asarray(values, dtype=float).ravel(), nan=0.0), 0.0, 1.0)
    r = np.clip(1.5 - np.abs(4.0 * x - 3.0), 0.0, 1.0)
    g = np.clip(1.5 - np.abs(4.0 * x - 2.0), 0.0, 1.0)
    b = np.clip(1.5 - np.abs(4.0 * x - 1.0), 0.0, 1.0)
    return np.column_stack([r, g, b, np.ones_like(x)])


class TaxelPadVisualizer(LeafSystem):
    """Draws every pad of a :class:`~mmlearn.systems.tactile.sensor.TactileSensor` as a grid
    of small boxes in Meshcat, one per cell, coloured by the cell's reading
    (:func:`taxel_colors`) and raised from the pad by ``bar_height`` x reading, so the
    pressure image is visible while the object hides the pad itself: the display sits
    ``display_depth`` behind the pad surface (on the finger's outer face, along -z_P).

    Publishes at ``period`` (the sensor's rate); if Meshcat is recording (``StartRecording``,
    e.g. by a ``MeshcatVisualizer``), the pad poses, colours and bar heights go into the
    recording as well (keyed at the context time). NaN readings are drawn as 0 and values
    outside [0, ``full_scale``] clipped, so a bad reading never stops a running simulation.

    Colour scale: a reading of 0 is dark blue, ``full_scale`` (default 1, the sensor's
    saturation) red, in the five steps of ``LEVELS`` (each cell holds one box per level
    under ``<prefix>/<pad>/rRRcCC/<k>`` and shows the nearest level's: a Meshcat recording
    replays visibility, not colour changes). A firm grasp reads far below saturation (0.2-0.3 at 20 N on the PR2
    pads), so with the default every cell looks alike; :meth:`recolor_recording` redraws a
    finished recording on a scale fitted to its readings (state the scale in the legend).

    .. pydrake_system::

        name: TaxelPadVisualizer
        input_ports:
        - taxels
        - body_poses

    ``taxels``: the sensor's readings (pad after pad, row-major, in [0, 1]);
    ``body_poses``: the plant's body poses (for the pads' bodies).
    """

    def __init__(self, *, meshcat, pads, period: float = 0.04, prefix: str = "taxels",
                 display_depth: float = 0.0125, bar_height: float = 0.004,
                 cell_fill: float = 0.9, full_scale: float = 1.0):
        """
        Args:
            meshcat: the Meshcat instance.
            pads: the sensor's PadSpec tuple (``TactileSensor.pads``).
            period: publish period, s.
            prefix: Meshcat path under which the pads are drawn.
            display_depth: distance of the display behind the pad surface (along -z_P), m.
            bar_height: thickness of a saturated cell's box, m (an empty cell: 5 %).
            cell_fill: box side as a fraction of the cell pitch (gaps between cells).
            full_scale: the reading drawn red and at full ``bar_height`` (in (0, 1]).
        """
        super().__init__()
        pads = tuple(pads)
        if not pads:
            raise ValueError("TaxelPadVisualizer: no pads")
        for k, v in (("period", period), ("display_depth", display_depth),
                     ("bar_height", bar_height)):
            if not (np.isfinite(v) and v >= 0) or (k != "display_depth" and v <= 0):
                raise ValueError(f"TaxelPadVisualizer: {k} must be a positive number, got {v!r}")
        if not (np.isfinite(full_scale) and 0 < full_scale <= 1):
            raise ValueError(f"TaxelPadVisualizer: full_scale must be in (0, 1], got {full_scale!r}")
        self._full_scale = float(full_scale)
        if not (0 < cell_fill <= 1):
            raise ValueError(f"TaxelPadVisualizer: cell_fill must be in (0, 1], got {cell_fill!r}")
        self._meshcat, self._pads, self._prefix = meshcat, pads, prefix.rstrip("/")
        self._bar = float(bar_height)
        self._sizes = [p.layout.rows * p.layout.cols for p in pads]
        self._offsets = np.concatenate([[0], np.cumsum(self._sizes)]).astype(int)
        # display frame D in the pad frame P: behind the surface, bars growing along -z_P
        self._X_PD = RigidTransform([0.0, 0.0, -float(display_depth)])
        self._cells = []  # per pad: (paths, centres (n, 3) in D)
        for pad in pads:
            L = pad.layout
            cw, ch = L.width / L.cols, L.length / L.rows
            paths, centres = [], []
            for r in range(L.rows):
                for c in range(L.cols):
                    path = f"{self._prefix}/{pad.name}/r{r:02d}c{c:02d}"
                    # one box per colour level, only the reading's level visible: a
                    # recording animates visibility (a colour change does not replay)
                    for k, rgba in enumerate(taxel_colors(LEVELS)):
                        meshcat.SetObject(f"{path}/{k}", Box(cw * cell_fill, ch * cell_fill, 1.0),
                                          Rgba(*rgba))
                        meshcat.SetProperty(f"{path}/{k}", "visible", k == 0)
                    paths.append(path)
                    centres.append((-L.width / 2 + (c + 0.5) * cw,
                                    L.length / 2 - (r + 0.5) * ch))
            self._cells.append((paths, np.array(centres)))
        self._taxels = self.DeclareVectorInputPort("taxels", int(self._offsets[-1]))
        self._poses = self.DeclareAbstractInputPort("body_poses",
                                                    AbstractValue.Make([RigidTransform()]))
        self.DeclarePeriodicPublishEvent(period, 0.0, self._publish)
        self.DeclareForcedPublishEvent(self._publish)

    def get_taxels_input_port(self):
        return self._taxels

    def get_body_poses_input_port(self):
        return self._poses

    def _publish(self, context):
        x = np.asarray(self._taxels.Eval(context), dtype=float)
        poses = self._poses.Eval(context)
        rec = {"time_in_recording": float(context.get_time())}
        for i, pad in enumerate(self._pads):
            X_WD = poses[pad.body_index] @ pad.X_BP @ self._X_PD
            self._meshcat.SetTransform(f"{self._prefix}/{pad.name}", X_WD, **rec)
        self._draw_cells(x, self._full_scale, rec)

    def _draw_cells(self, x, full_scale: float, rec: dict) -> None:
        """Show every cell's level and raise it for the readings ``x`` (all pads) on
        ``full_scale``."""
        mc = self._meshcat
        n_lev = len(LEVELS)
        for i in range(len(self._pads)):
            vals = np.clip(np.nan_to_num(x[self._offsets[i]:self._offsets[i + 1]], nan=0.0)
                           / full_scale, 0.0, 1.0)
            h = self._bar * (0.05 + 0.95 * vals)
            level = np.rint(vals * (n_lev - 1)).astype(int)
            paths, centres = self._cells[i]
            for path, (cx, cy), hk, lev in zip(paths, centres, h, level):
                mc.SetTransform(path, RigidTransform([cx, cy, -hk / 2]), **rec)
                mc.SetProperty(path, "scale", [1.0, 1.0, float(hk)], **rec)
                for k in range(n_lev):
                    mc.SetProperty(f"{path}/{k}", "visible", bool(k == lev), **rec)

    def recolor_recording(self, times, readings, full_scale: float | None = None) -> float:
        """Redraw the cells of a Meshcat recording that is still open (before
        ``StopRecording``) on another colour scale: ``readings`` (T, n) are the taxel
        readings at ``times`` (T,) s, e.g. from a ``LogVectorOutput`` of the sensor's
        ``taxels`` port at the visualizer's period. ``full_scale`` (default: the largest
        reading rounded up to a multiple of 0.05) is drawn red and at full height. Only the
        cells' colours and heights are re-keyed; the pads' poses stay as recorded. Returns
        the scale used."""
        R = np.asarray(readings, dtype=float).reshape(len(times), -1)
        if R.shape[1] != self._offsets[-1]:
            raise ValueError(f"TaxelPadVisualizer: readings need {self._offsets[-1]} columns, "
                             f"got {R.shape[1]}")
        if full_scale is None:
            top = float(np.nanmax(R)) if R.size and np.isfinite(np.nanmax(R)) else 0.0
            full_scale = float(np.clip(np.ceil(top / 0.05 - 1e-9) * 0.05, 0.05, 1.0))
        if not (np.isfinite(full_scale) and 0 < full_scale <= 1):
            raise ValueError(f"TaxelPadVisualizer: full_scale must be in (0, 1], got {full_scale!r}")
        for t, x in zip(times, R):
            self._draw_cells(x, float(full_scale), {"time_in_recording": float(t)})
        return float(full_scale)
