"""Observation tracks of the simulated articulated objects (sdf/objects.py).

Each object is parsed into a MultibodyPlant; for every sample the joint configuration is
set kinematically and the pose of every ``<part>_marker`` frame is read and perturbed with
Gaussian noise (sigma_pos m per axis, sigma_orient rad per rotation-vector axis). Static root
parts (cabinet, floor, car, garage frame) carry a larger marker: their noise is scaled down
(``*_noise_scale``), otherwise their orientation noise times the lever arm to the moving
part (up to 2 m) would dominate the relative poses. Parts can
be hidden per sample (NaN rows). Scenarios reproduce the experiments of thesis 4.4.1/4.4.3.

All functions return ``ObjectTrack``: ``poses`` (p, T, 7) x y z qx qy qz qw, ``q`` (T, nq)
the joint configuration, ``parts`` and ``joints`` names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from mmlearn.sdf.objects import (add_object, garage_door_configuration, object_parts,
                                 yardstick_closed_configuration)

__all__ = ["ObjectTrack", "ObjectKinematics", "cabinet_scenario", "cabinet_together_scenario",
           "yardstick_scenario",
           "table_scenario", "table_phases", "car_door_scenario", "garage_door_scenario", "SCENARIOS"]



@dataclass
class ObjectTrack:
    name: str
    parts: list
    joints: list
    poses: np.ndarray  # (p, T, 7)
    poses_true: np.ndarray  # (p, T, 7)
    q: np.ndarray  # (T, nq)


class ObjectKinematics:
    """A finalized plant holding one object; ``marker_poses(q)`` -> (p, T, 7)."""

    def __init__(self, name: str):
        from pydrake.multibody.plant import DiscreteContactApproximation, MultibodyPlant

        self.name = name
        self.plant = MultibodyPlant(time_step=1e-3)
        self.plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
        self.instance, self.constraints = add_object(self.plant, name)
        self.plant.Finalize()
        self.context = self.plant.CreateDefaultContext()
        self.parts = object_parts(name)
        self.frames = [self.plant.GetFrameByName(f"{p}_marker", self.instance)
                       for p in self.parts]
        self.joints = [self.plant.get_joint(j).name()
                       for j in self.plant.GetJointIndices(self.instance)
                       if self.plant.get_joint(j).num_positions() == 1]

    def marker_poses(self, q) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, float))
        nq = self.plant.num_positions(self.instance)
        if q.shape[1] != nq:
            raise ValueError(f"{self.name}: configurations need {nq} columns, got {q.shape[1]}")
        out = np.zeros((len(self.parts), q.shape[0], 7))
        for t in range(q.shape[0]):
            self.plant.SetPositions(self.context, self.instance, q[t])
            for k, f in enumerate(self.frames):
                X = f.CalcPoseInWorld(self.context)
                out[k, t, :3] = X.translation()
                out[k, t, 3:] = Rotation.from_matrix(X.rotation().matrix()).as_quat()
        return out


_KIN = {}


def _kin(name) -> ObjectKinematics:
    if name not in _KIN:
        _KIN[name] = ObjectKinematics(name)
    return _KIN[name]


def _track(name, q, sigma_pos, sigma_orient, rng, hidden=None, scale=None) -> ObjectTrack:
    """``scale``: per-part noise factors (p,), e.g. a larger marker on a static part."""
    kin = _kin(name)
    true = kin.marker_poses(q)
    p, T, _ = true.shape
    sc = np.ones(p) if scale is None else np.asarray(scale, float)
    noisy = true.copy()
    noisy[..., :3] += rng.normal(0, sigma_pos, (p, T, 3)) * sc[:, None, None]
    R = Rotation.from_rotvec((rng.normal(0, sigma_orient, (p, T, 3)) * sc[:, None, None]).reshape(
        -1, 3)) * Rotation.from_quat(true[..., 3:].reshape(-1, 4))
    noisy[..., 3:] = R.as_quat().reshape(p, T, 4)
    if hidden is not None:
        noisy[hidden] = np.nan
    return ObjectTrack(name, kin.parts, kin.joints, noisy, true, np.asarray(q, float))


def cabinet_scenario(n_first: int = 20, n_both: int = 40, *, sigma_pos: float = 0.003,
                     sigma_orient: float = np.deg2rad(1), cabinet_noise_scale: float = 0.2,
                     rng=None) -> ObjectTrack:
    """Fig. 4.8: the lower drawer alone opens and closes for ``n_first`` samples, then both
    drawers move independently. q = (upper_slide, lower_slide) in metres. The cabinet
    carries a larger marker (noise x ``cabinet_noise_scale``): with equal noise the trees
    {(1,2),(1,3)} and {(1,2),(2,3)} explain parallel drawers equally well."""
    rng = np.random.default_rng(rng)
    q = np.zeros((n_first + n_both, 2))
    q[:n_first, 1] = 0.2 - 0.2 * np.cos(np.linspace(0, 2 * np.pi, n_first))
    q[n_first:, 0] = rng.uniform(0, 0.4, n_both)
    q[n_first:, 1] = rng.uniform(0, 0.4, n_both)
    return _track("two_drawer_cabinet", q, sigma_pos, sigma_orient, rng,
                  scale=[cabinet_noise_scale, 1.0, 1.0])


def cabinet_together_scenario(n: int = 40, *, sigma_pos: float = 0.003,
                              sigma_orient: float = np.deg2rad(1),
                              cabinet_noise_scale: float = 0.2, rng=None) -> ObjectTrack:
    """The Fig. 4.8 cabinet with both drawers only ever pulled together (thesis Sec. 9.1's
    ambiguous case): q = (s, s) with s opening and closing twice, 0..0.4 m, plus a small
    independent jitter of 1 mm per drawer. The data cannot tell "both drawers slide in the
    cabinet" from "one drawer is fixed to the other"
    (:class:`~mmlearn.models.articulation.structure_prior.StructurePrior` decides)."""
    rng = np.random.default_rng(rng)
    s = 0.2 - 0.2 * np.cos(np.linspace(0, 4 * np.pi, n))
    q = np.stack([s, s], axis=1) + rng.normal(0.0, 0.001, (n, 2))
    return _track("two_drawer_cabinet", np.clip(q, 0.0, None), sigma_pos, sigma_orient, rng,
                  scale=[cabinet_noise_scale, 1.0, 1.0])


def yardstick_scenario(closed: bool, n: int = 200, *, sigma_pos: float = 0.005,
                       sigma_orient: float = np.deg2rad(3), staged: bool = False,
                       rng=None) -> ObjectTrack:
    """Sec. 4.4.3: open chain (3 independent hinge angles uniform in [-1.2, 1.2] rad) or the
    closed rhombus (opening angle uniform in [0.5, 2.6] rad). ``staged`` (open chain): the
    hinges start moving one after the other, at 1/4, 2/4 and 3/4 of the samples (Fig. 4.17a)."""
    rng = np.random.default_rng(rng)
    if closed:
        q = yardstick_closed_configuration(rng.uniform(0.5, 2.6, n))
        name = "yardstick_closed"
    else:
        q = rng.uniform(-1.2, 1.2, (n, 3))
        if staged:
            for k in range(3):
                q[: (k + 1) * n // 4, k] = 0.0
        name = "yardstick_open"
    return _track(name, q, sigma_pos, sigma_orient, rng)


def table_phases(n_per_phase: int = 15, *, push_m: float = 0.8) -> dict:
    """Sample counts of the phases of :func:`table_scenario`: ``still``, ``line`` (both
    ``n_per_phase``), ``curve`` (quarter circle of radius ``push_m`` turning sideways, then
    ``push_m`` straight sideways) and ``free`` (``2 n_per_phase``). The table is pushed at a
    constant speed (one sample per ``push_m / (n_per_phase - 1)`` m of travel), so the curved
    phase has as many samples as its path length (pi/2 + 1) push_m needs."""
    m = int(n_per_phase)
    if m < 2:
        raise ValueError(f"table_scenario needs n_per_phase >= 2, got {n_per_phase}")
    step = push_m / (m - 1)
    return {"still": m, "line": m, "curve": int(round((np.pi / 2 + 1) * push_m / step)),
            "free": 2 * m}


def table_scenario(n_per_phase: int = 15, *, sigma_pos: float = 0.01,
                   sigma_orient: float = np.deg2rad(1), root_noise_scale: float = 0.1,
                   push_m: float = 0.8, rng=None) -> ObjectTrack:
    """Fig. 4.9 (thesis 4.4.1): the table stands still, is pushed ``push_m`` along x
    ("moved in one direction only"), then turns along a quarter circle (r = ``push_m``) and
    is pushed ``push_m`` sideways along y ("after moving sideways": a curved 1-D path), then
    moved freely over the floor (never turned). Pushing is at a constant speed: samples are
    equally spaced along the 1-D path (:func:`table_phases`). q = (x, y, yaw)."""
    rng = np.random.default_rng(rng)
    ph = table_phases(n_per_phase, push_m=push_m)
    m, L = ph["line"], push_m
    still = np.zeros((ph["still"], 2))
    line = np.stack([L * np.linspace(0, 1, m), np.zeros(m)], 1)
    # curved phase parametrised by arc length u in (0, (pi/2 + 1) L]: arc, then straight
    u = np.linspace(0, (np.pi / 2 + 1) * L, ph["curve"] + 1)[1:]
    a = np.minimum(u / L, np.pi / 2)  # turning angle on the arc
    side = np.maximum(u - np.pi / 2 * L, 0.0)  # straight sideways travel after the arc
    curve = np.stack([L + L * np.sin(a), L - L * np.cos(a) + side], 1)
    free = np.stack([rng.uniform(-0.5, 1.8, ph["free"]), rng.uniform(-0.8, 1.2, ph["free"])], 1)
    xy = np.vstack([still, line, curve, free])
    q = np.hstack([xy, np.zeros((xy.shape[0], 1))])
    return _track("table", q, sigma_pos, sigma_orient, rng, scale=[root_noise_scale, 1.0])


def car_door_scenario(n_window: int = 40, n_door: int = 40, *, sigma_pos: float = 0.002,
                      sigma_orient: float = np.deg2rad(0.3), root_noise_scale: float = 0.1,
                      rng=None) -> ObjectTrack:
    """Fig. 4.11: the window is lowered on its curved guide (door closed), then the door
    opens. q = (door_hinge rad, window_guide rad); window travel 0.45 m on r = 1.9 m."""
    rng = np.random.default_rng(rng)
    w = np.concatenate([np.zeros(5), np.linspace(0, -0.24, n_window - 5)])
    q = np.zeros((n_window + n_door, 2))
    q[:n_window, 1] = w
    q[n_window:, 1] = -0.24
    q[n_window:, 0] = -np.linspace(0, 1.1, n_door)
    return _track("car_door", q, sigma_pos, sigma_orient, rng,
                  scale=[root_noise_scale, 1.0, 1.0])


def garage_door_scenario(n: int = 60, *, sigma_pos: float = 0.01,
                         sigma_orient: float = np.deg2rad(1), root_noise_scale: float = 0.1,
                         rng=None) -> ObjectTrack:
    """Roll-up garage door opened along its whole path (Fig. 4.19)."""
    rng = np.random.default_rng(rng)
    s = np.linspace(0, 2.2, n)
    return _track("garage_door", garage_door_configuration(s), sigma_pos, sigma_orient, rng,
                  scale=[root_noise_scale, 1.0])


SCENARIOS = {"two_drawer_cabinet": cabinet_scenario,
             "yardstick_open": lambda **kw: yardstick_scenario(False, **kw),
             "yardstick_closed": lambda **kw: yardstick_scenario(True, **kw),
             "table": table_scenario, "car_door": car_door_scenario,
             "garage_door": garage_door_scenario}


# ------------------------------------------------------------------ camera observations
def auto_cameras(poses_true, *, fov_y_deg: float = 55.0, aspect: float = 4 / 3,
                 min_distance: float = 1.0, fill: float = 0.7, elevation_deg: float = 0.0):
    """One camera that sees every marker of a track: on the side the markers face on
    average (the mean of their normals over the track; straight above when they cancel),
    raised by ``elevation_deg`` degrees above that direction (at most 80 deg above the
    horizon; e.g. to look over a drawer front onto a marker just above it), far enough
    that the markers' spread fills at most ``fill`` of the smaller half field of view, at
    least ``min_distance`` m; looking at the markers' centroid.

    Args:
        poses_true: (p, T, 7) true marker poses of the track.
    Returns:
        [CameraConfig].
    """
    from mmlearn.systems.common.marker_sensor import CameraConfig

    P = np.asarray(poses_true, float)
    pts = P[..., :3].reshape(-1, 3)
    normals = Rotation.from_quat(P[..., 3:].reshape(-1, 4)).as_matrix()[:, :, 2]
    c = pts.mean(axis=0)
    n = normals.mean(axis=0)
    if np.linalg.norm(n) < 0.2:
        n = np.array([0.0, 0.0, 1.0])
    n /= np.linalg.norm(n)
    if elevation_deg and np.linalg.norm(n[:2]) > 1e-6:
        el = min(math.asin(float(np.clip(n[2], -1, 1))) + math.radians(elevation_deg),
                 math.radians(80.0))
        h = n[:2] / np.linalg.norm(n[:2])
        n = np.array([h[0] * math.cos(el), h[1] * math.cos(el), math.sin(el)])
    # nudge a vertical view off the world's up axis (CameraConfig keeps +z up in the image)
    if abs(n[2]) > 0.98:
        n = np.array([0.15, 0.0, 1.0]) / np.linalg.norm([0.15, 0.0, 1.0])
    radius = float(np.max(np.linalg.norm(pts - c, axis=1))) + 0.05
    half = math.radians(fov_y_deg) / 2
    dist = max(min_distance, radius / (fill * math.tan(half)))
    return [CameraConfig(position=list(c + dist * n), look_at=list(c), fov_y_deg=fov_y_deg,
                         fov_x_deg=math.degrees(2 * math.atan(aspect * math.tan(half))),
                         max_range=dist + radius + 1.0)]


def _cabinet_edge_mount():
    """The two-drawer cabinet's ArUco square on a 45-degree holder on the cabinet's top
    front edge (centre 0.04 m behind the front, 0.03 m above the top, normal halfway between
    forwards and up), as a pose in the cabinet's marker frame (on the front face, normal +x,
    0.03 m below the top). A square on the marker frame itself is cut by the upper drawer's
    front, which juts 2 cm out just below it (a closed upper drawer hid the square's lower
    corner and the camera never read it); one flat on the top face is seen too obliquely
    (> 70 deg) from a camera that sees the drawers' fronts."""
    from pydrake.math import RigidTransform, RotationMatrix

    # marker frame axes in the world: x = -z_W, y = y_W, z = x_W; the holder's centre
    # (-0.04, 0.2, 0.53) is (-0.06, 0, -0.041) from the marker's origin (0.001, 0.2, 0.47)
    return RigidTransform(RotationMatrix.MakeYRotation(-math.pi / 4), [-0.06, 0.0, -0.041])


#: Where the camera's ArUco squares go when a part's marker frame is a bad place for a
#: printed square ({object: {part: callable returning X_MS}}, see ``AddArucoMarkers``).
CAMERA_MARKER_MOUNTS = {"two_drawer_cabinet": {"cabinet": _cabinet_edge_mount}}
#: Printed marker size and quiet zone (m) per object whose automatic camera stands far
#: away: the table's, car's and garage's markers spread over 2-3 m, so the camera is
#: 4-6 m away, where the 0.04 m squares are 9-14 px wide and were not read (or 36 mm off).
CAMERA_MARKER_SIZE = {"table": (0.25, 0.03), "car_door": (0.12, 0.02),
                      "garage_door": (0.12, 0.02)}
#: Degrees the automatic camera is raised above the markers' mean normal per object (the
#: cabinet's square on its 45-degree holder and the drawers' fronts both in view).
CAMERA_ELEVATION_DEG = {"two_drawer_cabinet": 30.0}


class ObjectCamera:
    """An object's marker squares with ArUco textures, rendered by RGB cameras and read by a
    :class:`~mmlearn.systems.common.camera_marker_sensor.CameraMarkerSensor`; ``observe(q)``
    returns the camera's (p, T, 7) poses of the parts' markers (NaN rows where a marker was
    not detected). A part listed in :data:`CAMERA_MARKER_MOUNTS` carries its square
    elsewhere on the part; its reports are mapped back to its marker frame."""

    def __init__(self, name: str, config):
        from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
        from pydrake.systems.framework import DiagramBuilder

        from mmlearn.diagrams.common.marker_camera import AddArucoMarkers, AddCameraMarkerSensor

        self.name = name
        builder = DiagramBuilder()
        plant, sg = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
        self.instance, _ = add_object(plant, name)
        self.parts = object_parts(name)
        mounts = {p: f() for p, f in CAMERA_MARKER_MOUNTS.get(name, {}).items()}
        markers = AddArucoMarkers(plant, config=config, model_instance=self.instance,
                                  bodies=self.parts, mounts=mounts)
        # X_SM per part (identity for the squares on their marker frames)
        self._X_SM = [mounts[p].inverse() if p in mounts else None for p in self.parts]
        plant.Finalize()
        self.sensor, self.rgbd = AddCameraMarkerSensor(builder, sg, markers=markers,
                                                       config=config)
        self.diagram = builder.Build()
        self.plant = plant
        self.context = self.diagram.CreateDefaultContext()

    def observe(self, q, *, progress=None) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, float))
        pc = self.plant.GetMyMutableContextFromRoot(self.context)
        sc = self.sensor.GetMyContextFromRoot(self.context)
        out = np.full((len(self.parts), q.shape[0], 7), np.nan)
        rows = range(q.shape[0]) if progress is None else progress(range(q.shape[0]))
        dt = 1.0 / self.sensor.config.rate_hz
        for t in rows:
            self.plant.SetPositions(pc, self.instance, q[t])
            # consecutive rows are consecutive sensor frames (ambiguous detections are
            # resolved against the previous reports)
            self.context.SetTime(t * dt)
            obs = self.sensor.observe_and_remember(sc)
            for k in range(len(self.parts)):
                if not obs.visible[k]:
                    continue
                X = obs.poses[k] if self._X_SM[k] is None else obs.poses[k] @ self._X_SM[k]
                out[k, t, :3] = X.translation()
                out[k, t, 3:] = Rotation.from_matrix(X.rotation().matrix()).as_quat()
        return out


def default_camera_config(track: ObjectTrack):
    """The camera marker sensor :func:`camera_track` uses by default for ``track``: 1920 x
    1440 images, one camera placed by :func:`auto_cameras` (raised by
    :data:`CAMERA_ELEVATION_DEG`), markers of :data:`CAMERA_MARKER_SIZE` (default 0.04 m)."""
    from mmlearn.sdf.aruco import ArucoSpec
    from mmlearn.systems.common.camera_marker_sensor import CameraMarkerSensorConfig

    kw = {}
    if track.name in CAMERA_MARKER_SIZE:
        size, margin = CAMERA_MARKER_SIZE[track.name]
        kw["aruco"] = ArucoSpec(marker_size=size, margin=margin)
    return CameraMarkerSensorConfig(cameras=auto_cameras(
        track.poses_true, elevation_deg=CAMERA_ELEVATION_DEG.get(track.name, 0.0)), **kw)


def camera_track(track: ObjectTrack, config=None, *, progress=None) -> ObjectTrack:
    """The same motion observed by the camera marker sensor instead of the Gaussian noise
    model: ``poses`` are the ArUco detections in rendered images (NaN where a marker was not
    detected), ``poses_true`` and ``q`` unchanged. ``config``: a CameraMarkerSensorConfig
    (default: :func:`default_camera_config`)."""
    if config is None:
        config = default_camera_config(track)
    cam = ObjectCamera(track.name, config)
    poses = cam.observe(track.q, progress=progress)
    return ObjectTrack(track.name, list(track.parts), list(track.joints), poses,
                       track.poses_true.copy(), track.q.copy())
