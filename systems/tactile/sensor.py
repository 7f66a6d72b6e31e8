"""TactileSensor: taxel pads reading the plant's hydroelastic contact pressure (ch. 6-7)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import ContactResults
from pydrake.systems.framework import LeafSystem

from mmlearn.models.tactile.pad import PadLayout, integrate_pressure_pads, sensor_reading

__all__ = ["PadSpec", "TactileSensor", "surface_triangles"]


@dataclass(frozen=True)
class PadSpec:
    """One finger pad of a :class:`TactileSensor`.

    Attributes:
        name: pad name (e.g. "left").
        layout: cell geometry and saturation (:class:`~mmlearn.models.tactile.pad.PadLayout`).
        body_index: int index of the plant body carrying the pad.
        X_BP: pose of the pad frame P in the body frame B (pad surface z_P = 0, normal +z_P
            towards the object, rows along y_P with row 0 at +y_P).
        geometry_ids: the pad's collision geometries (GeometryId); only contact surfaces
            involving one of them are integrated.
    """

    name: str
    layout: PadLayout
    body_index: int
    X_BP: RigidTransform
    geometry_ids: tuple


def surface_triangles(surface) -> tuple[np.ndarray, np.ndarray]:
    """Triangles (n, 3, 3) in world and vertex pressures (n, 3), Pa, of a Drake
    ``ContactSurface`` (polygon surfaces are fan-triangulated: their pressure field is linear
    over each polygon, so the vertex values interpolate it exactly)."""
    if surface.is_triangle():
        mesh, field = surface.tri_mesh_W(), surface.tri_e_MN()
        nv = mesh.num_vertices()
        V = np.array([mesh.vertex(i) for i in range(nv)]).reshape(nv, 3)
        p = np.array([field.EvaluateAtVertex(i) for i in range(nv)])
        F = np.array([[t.vertex(0), t.vertex(1), t.vertex(2)] for t in mesh.triangles()],
                     dtype=int).reshape(-1, 3)
        return V[F], p[F]
    mesh, field = surface.poly_mesh_W(), surface.poly_e_MN()
    nv = mesh.num_vertices()
    V = np.array([mesh.vertex(i) for i in range(nv)]).reshape(nv, 3)
    p = np.array([field.EvaluateAtVertex(i) for i in range(nv)])
    data = np.asarray(mesh.face_data(), dtype=int)  # n, i_1 .. i_n, n, ...
    starts, k = [], 0
    while k < len(data):
        starts.append(k)
        k += int(data[k]) + 1
    starts = np.array(starts, dtype=int)
    ntri = np.maximum(data[starts] - 2, 0)  # fan of each polygon
    fid = np.repeat(np.arange(len(starts)), ntri)
    j = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    base = starts[fid] + 1
    F = np.column_stack([data[base], data[base + j], data[base + j + 1]]).reshape(-1, 3)
    return V[F], p[F]


def _real(x) -> bool:
    """A real number (not a bool, a string or None)."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


class TactileSensor(LeafSystem):
    """Taxel pads on the fingers, sampled at ``rate_hz`` from hydroelastic contact.

    On every sample the pressure field of each hydroelastic contact surface touching a pad's
    geometry is integrated over the pad's cells (:func:`integrate_pressure`: each face is
    clipped exactly against the cells, so sliver faces are area-weighted correctly), normalised by the pad's
    saturation pressure, given seeded Gaussian noise (drawn from (seed, sample index), so
    two simulators of the same diagram agree) and clipped to [0, 1]. The force of each pad
    is the calibrated sum of its readings: ``sum(reading) * p_sat * cell_area`` (N).
    Point contacts (the hydroelastic fallback) are not seen: pads must be hydroelastic.

    .. pydrake_system::

        name: TactileSensor
        input_ports:
        - contact_results
        - body_poses
        output_ports:
        - taxels
        - pad_force

    ``taxels``: all pads' readings, pad after pad, each ``rows * cols`` row-major, in [0, 1].
    ``pad_force``: the normal force on each pad, N (held between samples).
    """

    def __init__(self, *, pads, rate_hz: float = 25.0, noise: float = 0.01, seed: int = 0):
        super().__init__()
        pads = tuple(pads)
        if not pads:
            raise ValueError("TactileSensor: no pads")
        if not (_real(rate_hz) and np.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"TactileSensor: rate_hz must be a finite number > 0, got {rate_hz!r}")
        if not (_real(noise) and np.isfinite(noise) and noise >= 0):
            raise ValueError(f"TactileSensor: noise must be a finite number >= 0, got {noise!r}")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"TactileSensor: seed must be an integer >= 0, got {seed!r}")
        self._pads = pads
        self._rate, self._noise, self._seed = rate_hz, noise, int(seed)
        self._sizes = [p.layout.rows * p.layout.cols for p in pads]
        self._offsets = np.concatenate([[0], np.cumsum(self._sizes)])
        self._gid = {}
        for i, p in enumerate(pads):
            for g in p.geometry_ids:
                self._gid[g] = i
        n = int(self._offsets[-1])
        self._contact = self.DeclareAbstractInputPort("contact_results",
                                                      AbstractValue.Make(ContactResults()))
        self._poses = self.DeclareAbstractInputPort("body_poses",
                                                    AbstractValue.Make([RigidTransform()]))
        self._taxel_state = self.DeclareDiscreteState(n)
        self._force_state = self.DeclareDiscreteState(len(pads))
        self.DeclarePeriodicDiscreteUpdateEvent(1.0 / rate_hz, 0.0, self._update)
        self._taxels = self.DeclareStateOutputPort("taxels", self._taxel_state)
        self._force = self.DeclareStateOutputPort("pad_force", self._force_state)

    @property
    def pads(self) -> tuple:
        return self._pads

    def get_contact_results_input_port(self):
        return self._contact

    def get_body_poses_input_port(self):
        return self._poses

    def get_taxels_output_port(self):
        return self._taxels

    def get_pad_force_output_port(self):
        return self._force

    def split(self, taxels) -> dict:
        """Pad name -> (rows, cols) image of a ``taxels`` vector (or (T, n) -> (T, rows, cols))."""
        x = np.asarray(taxels)
        out = {}
        for i, p in enumerate(self._pads):
            a = x[..., self._offsets[i]:self._offsets[i + 1]]
            out[p.name] = a.reshape(*x.shape[:-1], p.layout.rows, p.layout.cols)
        return out

    def cell_pressures(self, context) -> list:
        """Noise-free mean pressure per cell (Pa) of each pad, list of (rows, cols)."""
        results = self._contact.Eval(context)
        poses = self._poses.Eval(context)
        tris = [[] for _ in self._pads]
        prs = [[] for _ in self._pads]
        for k in range(results.num_hydroelastic_contacts()):
            s = results.hydroelastic_contact_info(k).contact_surface()
            i = self._gid.get(s.id_M(), self._gid.get(s.id_N()))
            if i is None:
                continue
            T, P = surface_triangles(s)
            tris[i].append(T)
            prs[i].append(P)
        # pads of the same layout are integrated in one vectorised pass
        out = [None] * len(self._pads)
        groups = {}
        for i, pad in enumerate(self._pads):
            groups.setdefault(pad.layout, []).append(i)
        for layout, idx in groups.items():
            T_P, P_P = [], []
            for i in idx:
                pad = self._pads[i]
                if not tris[i]:
                    T_P.append(np.zeros((0, 3, 3)))
                    P_P.append(np.zeros((0, 3)))
                    continue
                X_PW = (poses[pad.body_index] @ pad.X_BP).inverse()
                R, t = X_PW.rotation().matrix(), X_PW.translation()
                T_P.append(np.concatenate(tris[i]) @ R.T + t)
                P_P.append(np.concatenate(prs[i]))
            cells = integrate_pressure_pads(layout, T_P, P_P)
            for k, i in enumerate(idx):
                out[i] = cells[k]
        return out

    def _update(self, context, discrete_state):
        k = int(round(context.get_time() * self._rate))
        rng = np.random.default_rng([self._seed, k])
        try:
            cells = self.cell_pressures(context)
        except (RuntimeError, ValueError):  # a bad contact surface must not stop the run
            cells = [np.zeros((p.layout.rows, p.layout.cols)) for p in self._pads]
        vals, forces = [], []
        for pad, c in zip(self._pads, cells):
            r = sensor_reading(pad.layout, c, rng=rng, noise=self._noise)
            vals.append(r.ravel())
            forces.append(r.sum() * pad.layout.p_sat * pad.layout.cell_area)
        discrete_state.get_mutable_vector(0).SetFromVector(np.concatenate(vals))
        discrete_state.get_mutable_vector(1).SetFromVector(np.array(forces))
