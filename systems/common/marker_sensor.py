"""MarkerSensor: noisy, partially visible observations of the markers on a robot's parts.

The noise model follows the thesis (chapters 3 and 4):

* Gaussian position noise, standard deviation ``sigma_pos`` (m) per axis;
* orientation noise: the observed rotation is R_true * exp([w]x) with the rotation vector
  w ~ N(0, sigma_orient^2 I3) (rad);
* a ratio ``gamma`` of outliers: the pose is replaced by a position drawn uniformly in
  the workspace box and a uniformly random rotation;
* visibility: a marker is seen only when it is inside some camera's field of view and
  range, its face is turned towards that camera (angle between the marker normal and the
  line of sight below ``max_view_angle_deg``), and the line of sight is not blocked by
  other geometry (SceneGraph signed-distance queries sampled along the ray); plus a random
  drop-out rate.

Randomness is a pure function of (seed, frame index), so a run is reproducible and a
restarted simulation draws the same noise.
"""


import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import EventStatus, LeafSystem

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.se3 import project_to_so3

from mmlearn.systems.common.observations import MarkerObservations


@dataclass
class CameraConfig:
    """A camera that sees markers (pinhole field of view; Drake camera axes: z forward,
    x right, y down).

    Attributes:
        position: camera centre in the world, m.
        look_at: point the optical axis passes through, m.
        fov_x_deg, fov_y_deg: full horizontal / vertical field of view, degrees.
        max_range: markers farther than this are not detected, m.
    """

    position: list[float] = param([2.2, 0.0, 1.2], unit="m", length=3, elements=True,
                                  factory=True)
    look_at: list[float] = param([0.0, 0.0, 0.6], unit="m", length=3, elements=True,
                                 factory=True)
    fov_x_deg: float = param(70.0, unit="deg", gt=0, lt=180)
    fov_y_deg: float = param(55.0, unit="deg", gt=0, lt=180)
    max_range: float = param(6.0, unit="m", gt=0)

    def validate(self) -> None:
        """Raise ValueError naming the first invalid field (and a look_at equal to position)."""
        validate_fields(self)
        self.pose()

    def pose(self) -> RigidTransform:
        """X_WC built from position and look_at (world +z is 'up' in the image)."""
        p = np.asarray(self.position, float)
        z = np.asarray(self.look_at, float) - p
        if np.linalg.norm(z) < 1e-9:
            raise ValueError("CameraConfig.look_at must differ from position")
        z /= np.linalg.norm(z)
        x = np.cross(z, [0.0, 0.0, 1.0])
        if np.linalg.norm(x) < 1e-6:  # looking straight up/down
            x = np.cross(z, [1.0, 0.0, 0.0])
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        return RigidTransform(RotationMatrix(np.column_stack([x, y, z])), p)


@dataclass
class MarkerSensorConfig:
    """Configuration of a :class:`MarkerSensor` (load it with ``yaml_load_typed``).

    Attributes:
        bodies: names of the bodies whose markers are observed. Each body's marker frame is
            ``<body>_marker`` when the model has it, else the body frame. Empty = every body
            of the model instance that has a ``<body>_marker`` frame.
        rate_hz: observation frames per second (> 0).
        sigma_pos: position noise, m (>= 0).
        sigma_orient: orientation noise, rad (>= 0).
        gamma: outlier ratio in [0, 1).
        dropout: probability that a visible marker is missed anyway, in [0, 1).
        workspace_min, workspace_max: box outlier positions are drawn from, m.
        cameras: the cameras; a marker is visible when any camera sees it. Empty = no
            field-of-view, facing or occlusion test (every marker visible, up to drop-out).
        max_view_angle_deg: largest angle between marker normal and line of sight, degrees.
        check_occlusion: test the line of sight against the scene's geometry.
        occlusion_step: spacing of the samples along a line of sight, m.
        seed: seed of the noise.
    """

    bodies: list[str] = param([], factory=True)
    rate_hz: float = param(10.0, unit="Hz", gt=0)
    sigma_pos: float = param(0.0, unit="m", ge=0)
    sigma_orient: float = param(0.0, unit="rad", ge=0)
    gamma: float = param(0.0, ge=0, lt=1)
    dropout: float = param(0.0, ge=0, lt=1)
    workspace_min: list[float] = param([-1.5, -1.5, 0.0], unit="m", length=3, elements=True,
                                       factory=True)
    workspace_max: list[float] = param([1.5, 1.5, 2.0], unit="m", length=3, elements=True,
                                       factory=True)
    cameras: list[CameraConfig] = param(default_factory=lambda: [CameraConfig()],
                                        nested=CameraConfig)
    max_view_angle_deg: float = param(80.0, unit="deg", gt=0, le=180)
    check_occlusion: bool = param(True)
    occlusion_step: float = param(0.02, unit="m", gt=0)
    seed: int = param(0, integer=True, ge=0)

    def validate(self) -> None:
        """Raise ValueError naming the first invalid field."""
        validate_fields(self)
        if np.any(np.asarray(self.workspace_max) < np.asarray(self.workspace_min)):
            raise ValueError(f"MarkerSensorConfig: workspace_max must be >= workspace_min "
                             f"per axis (m), got {self.workspace_min} and {self.workspace_max}")


class MarkerSensor(LeafSystem):
    """Publishes noisy observations of the markers on a plant's bodies.

    .. pydrake_system::

        name: MarkerSensor
        input_ports:
        - body_poses
        - query_object (optional)
        output_ports:
        - observations
        - stats

    ``body_poses`` takes the plant's ``body_poses`` output; ``query_object`` takes the
    SceneGraph's ``query`` output and enables the occlusion test (left unconnected, no
    marker is ever occluded). ``observations`` is an abstract
    :class:`~mmlearn.systems.common.observations.MarkerObservations`, refreshed at ``rate_hz``
    (the first frame at t = 0). ``stats`` is [frames, marker observations, visible ones]
    counted since the start.
    """

    def __init__(self, *, plant, config: MarkerSensorConfig | None = None,
                 model_instance=None):
        """Args:
            plant: the finalized MultibodyPlant whose bodies carry the markers.
            config: the sensor's settings (default ``MarkerSensorConfig()``).
            model_instance: where ``config.bodies`` and their ``<body>_marker`` frames are
                looked up; with ``config.bodies`` empty, every body of this instance that
                has a ``<body>_marker`` frame is observed. Without a ``<body>_marker``
                frame a body's marker is its body frame (for a door: on the hinge, where
                it only turns in place: a radius near 0, or rigid); add one with
                ``plant.AddFrame(FixedOffsetFrame("<body>_marker", ...))`` before
                ``Finalize``. The marker ids of the observations are the body names.

        Raises ValueError for a bad config or a body the plant does not have."""
        super().__init__()
        cfg = config or MarkerSensorConfig()
        cfg.validate()
        self._cfg = cfg
        names = list(cfg.bodies)
        if not names:
            if model_instance is None:
                raise ValueError("MarkerSensor: give config.bodies or a model_instance")
            names = [plant.get_body(b).name() for b in plant.GetBodyIndices(model_instance)
                     if plant.HasFrameNamed(plant.get_body(b).name() + "_marker",
                                            model_instance)]
            if not names:
                raise ValueError("MarkerSensor: the model instance has no <body>_marker frames")
        self._names = names
        self._body_index, X_BM, self._frame_ids = [], [], []
        for n in names:
            try:
                body = (plant.GetBodyByName(n, model_instance) if model_instance is not None
                        else plant.GetBodyByName(n))
            except RuntimeError:
                known = sorted({plant.get_body(b).name()
                                for b in (plant.GetBodyIndices(model_instance)
                                          if model_instance is not None
                                          else range(plant.num_bodies()))})
                raise ValueError(f"MarkerSensor: unknown body {n!r}; known bodies: {known}")
            self._body_index.append(int(body.index()))
            mi = body.model_instance()
            if plant.HasFrameNamed(n + "_marker", mi):
                X_BM.append(plant.GetFrameByName(n + "_marker", mi).GetFixedPoseInBodyFrame())
            else:
                X_BM.append(RigidTransform())
            fid = plant.GetBodyFrameIdIfExists(body.index())
            self._frame_ids.append(fid)
        self._X_BM = X_BM
        self._cams = [(c.pose().inverse(), c) for c in cfg.cameras]
        self._cos_view = math.cos(math.radians(cfg.max_view_angle_deg))
        self._lo = np.asarray(cfg.workspace_min, float)
        self._hi = np.asarray(cfg.workspace_max, float)

        self._body_poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()]))
        self._query = self.DeclareAbstractInputPort("query_object", _query_value())
        self._obs_index = self.DeclareAbstractState(AbstractValue.Make(MarkerObservations()))
        self._stats_index = self.DeclareDiscreteState(3)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / cfg.rate_hz, 0.0, self._update)
        self._out = self.DeclareAbstractOutputPort(
            "observations", lambda: AbstractValue.Make(MarkerObservations()),
            self._calc_observations, {self.abstract_state_ticket(self._obs_index)})
        self._stats_out = self.DeclareStateOutputPort("stats", self._stats_index)

    # -- ports ---------------------------------------------------------------------------
    def get_body_poses_input_port(self):
        return self._body_poses

    def get_query_object_input_port(self):
        return self._query

    def get_observations_output_port(self):
        return self._out

    def get_stats_output_port(self):
        return self._stats_out

    @property
    def marker_ids(self) -> list[str]:
        return list(self._names)

    # -- computation ---------------------------------------------------------------------
    def true_marker_poses(self, context) -> list[RigidTransform]:
        """Noise-free marker poses X_WM for the given context of this system."""
        X_WB = self._body_poses.Eval(context)
        if len(X_WB) <= max(self._body_index, default=-1):
            raise ValueError(f"MarkerSensor: body_poses holds {len(X_WB)} poses but marker "
                             f"body {self._names[int(np.argmax(self._body_index))]!r} has "
                             f"index {max(self._body_index)} (connect the plant's "
                             "body_poses port)")
        return [X_WB[i] @ X for i, X in zip(self._body_index, self._X_BM)]

    def _visibility(self, poses, query) -> np.ndarray:
        m = len(poses)
        if not self._cams:
            return np.ones(m, bool)
        P = np.array([X.translation() for X in poses])          # (m, 3)
        N = np.array([X.rotation().matrix()[:, 2] for X in poses])  # marker normals
        seen = np.zeros(m, bool)
        for X_CW, cam in self._cams:
            p_C = (X_CW.rotation().matrix() @ P.T).T + X_CW.translation()
            rng = np.linalg.norm(p_C, axis=1)
            in_front = p_C[:, 2] > 1e-6
            with np.errstate(divide="ignore", invalid="ignore"):
                ax = np.abs(np.arctan2(p_C[:, 0], p_C[:, 2]))
                ay = np.abs(np.arctan2(p_C[:, 1], p_C[:, 2]))
            ok = (in_front & (ax <= math.radians(cam.fov_x_deg) / 2)
                  & (ay <= math.radians(cam.fov_y_deg) / 2) & (rng <= cam.max_range))
            to_cam = np.asarray(cam.position, float) - P
            dist = np.linalg.norm(to_cam, axis=1)
            ok &= np.einsum("ij,ij->i", N, to_cam) > self._cos_view * dist
            if query is not None and self._cfg.check_occlusion:
                for i in np.flatnonzero(ok & ~seen):
                    ok[i] = not self._occluded(P[i], np.asarray(cam.position, float),
                                               self._frame_ids[i], query)
            seen |= ok
        return seen

    def _occluded(self, p_marker, p_cam, own_frame, query) -> bool:
        """True when a sample on the segment camera -> marker lies inside geometry not
        attached to the marker's own body."""
        d = p_cam - p_marker
        length = float(np.linalg.norm(d))
        step = self._cfg.occlusion_step
        # start a little off the marker surface so the carrier's neighbours still count
        s = np.arange(0.01, length, step)
        inspector = query.inspector()
        for t in s:
            hits = query.ComputeSignedDistanceToPoint(p_marker + d * (t / length), 0.0)
            for h in hits:
                if h.distance < 0 and inspector.GetFrameId(h.id_G) != own_frame:
                    return True
        return False

    def observe(self, context, frame: int | None = None) -> MarkerObservations:
        """Draw one observation frame for this system's ``context``.

        ``frame`` selects the noise draw (default: the frame index of the context's time at
        ``rate_hz``); the periodic update calls this. Never raises on a bad scene state:
        a frame that cannot be computed sees nothing.
        """
        cfg = self._cfg
        t = context.get_time()
        k = int(round(t * cfg.rate_hz)) if frame is None else int(frame)
        if k < 0:
            raise ValueError(f"MarkerSensor.observe: frame must be >= 0, got {k}")
        rng = np.random.default_rng([cfg.seed, k])
        m = len(self._names)
        try:
            true_poses = self.true_marker_poses(context)
            query = self._query.Eval(context) if self._query.HasValue(context) else None
            visible = self._visibility(true_poses, query)
        except (RuntimeError, ValueError, FloatingPointError, IndexError, TypeError) as e:
            # a bad observation never ends the simulation: this frame sees nothing
            warnings.warn(f"MarkerSensor: frame {k} sees nothing ({e})", RuntimeWarning,
                          stacklevel=2)
            true_poses = [RigidTransform()] * m
            visible = np.zeros(m, bool)
        noise_p = rng.normal(0.0, 1.0, (m, 3)) * cfg.sigma_pos
        noise_r = rng.normal(0.0, 1.0, (m, 3)) * cfg.sigma_orient
        outlier = rng.random(m) < cfg.gamma
        dropped = rng.random(m) < cfg.dropout
        out_p = rng.uniform(self._lo, self._hi, (m, 3))
        out_R = Rotation.random(m, random_state=rng).as_matrix()
        dR = Rotation.from_rotvec(noise_r).as_matrix()
        poses = []
        for i, X in enumerate(true_poses):
            if outlier[i]:
                poses.append(RigidTransform(RotationMatrix(out_R[i]), out_p[i]))
            else:
                R = X.rotation().matrix() @ dR[i]
                if not np.all(np.isfinite(R)):  # a pose that cannot be computed: not seen
                    visible[i] = False
                    R = np.eye(3)
                poses.append(RigidTransform(RotationMatrix(project_to_so3(R)),
                                            X.translation() + noise_p[i]))
        visible = visible & ~dropped
        return MarkerObservations(time=t, marker_ids=list(self._names), poses=poses,
                                  visible=visible, outlier=outlier & visible)

    def _update(self, context, state):
        obs = self.observe(context)
        state.get_mutable_abstract_state(self._obs_index).set_value(obs)
        stats = state.get_mutable_discrete_state(self._stats_index)
        stats.set_value(stats.get_value() + np.array([1.0, len(obs), obs.visible.sum()]))
        return EventStatus.Succeeded()

    def _calc_observations(self, context, output):
        output.set_value(context.get_abstract_state(self._obs_index).get_value())


def _query_value():
    from pydrake.geometry import QueryObject

    return AbstractValue.Make(QueryObject())
