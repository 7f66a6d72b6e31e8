"""WristForceSensor: the force the environment exerts on the end effector, as a wrist
force-torque sensor between the last link and the tool would report it."""

import math

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialForce
from pydrake.systems.framework import EventStatus, LeafSystem


class WristForceSensor(LeafSystem):
    """Measures the external (contact) force on a tool welded to the arm.

    From the plant's joint reaction forces at the tool's mount joint (the force of the arm
    on the tool) and the tool's weight: in quasi-static conditions
    F_contact = -F_arm_on_tool - m_tool * g. Gaussian noise of ``sigma_force`` N per axis
    is added, a function of (seed, sample index) alone so runs are reproducible; the
    sample is held between updates at ``rate_hz``.

    Keywords beyond the noise and the rate:

    - ``plant_time_step``: 0 (the default) reads the inputs at each sample instant
      k / ``rate_hz``, one event per sample (with a plant whose output ports are live: the
      reaction forces of the step that starts at the instant and the tool's pose at its
      start). A plant with sampled output ports steps in an unrestricted update,
      before this sensor's discrete one: the sample is then the reaction forces of the
      step that starts at the instant, turned into the world frame with the tool's pose
      at that step's end. For a plant whose output ports are live (computed from the
      current state when read; the plant then computes the reaction forces only for the
      steps read), give its time step: the sensor then reads the reaction forces at each
      sample instant (the step that starts there) and makes the sample one plant step
      later with the tool's pose then: the same values. It holds them from that step on
      (one step after the instant: systems that read the force at the sample instants,
      or more than a step after them, see the same values as with sampled ports). The
      sample period must be two or more plant steps; the sensor has an event at every
      plant step (most do nothing).
    - ``noise_samples``: the noise of the first ``noise_samples`` samples is drawn at
      construction, in one block from the seed (a table read per sample instead of a new
      random generator per sample); later samples, and every sample when it is 0, draw
      theirs from a generator seeded by (seed, sample index). The two give different
      draws of the same distribution.

    .. pydrake_system::

        name: WristForceSensor
        input_ports:
        - reaction_forces
        - body_poses
        output_ports:
        - force_W

    ``force_W`` is the force on the tool in the world frame, N.
    """

    def __init__(self, *, plant, mount_joint, sigma_force: float = 0.3, rate_hz: float = 100.0,
                 seed: int = 0, plant_time_step: float = 0.0, noise_samples: int = 0):
        super().__init__()
        if sigma_force < 0 or not np.isfinite(sigma_force):
            raise ValueError(f"WristForceSensor: sigma_force must be >= 0, got {sigma_force}")
        if not rate_hz > 0:
            raise ValueError(f"WristForceSensor: rate_hz must be > 0, got {rate_hz}")
        period = 1.0 / rate_hz
        steps = period / plant_time_step if plant_time_step > 0 else 1.0
        if not (plant_time_step >= 0 and math.isfinite(plant_time_step)) \
                or abs(steps - round(steps)) > 1e-6 * steps \
                or (plant_time_step > 0 and round(steps) < 2):
            raise ValueError(f"WristForceSensor: plant_time_step must be 0 or divide the "
                             f"sample period {period:g} s into 2 or more steps, got "
                             f"{plant_time_step}")
        if isinstance(noise_samples, bool) or not isinstance(noise_samples, (int, np.integer)) \
                or noise_samples < 0:
            raise ValueError(f"WristForceSensor: noise_samples must be an integer >= 0, got "
                             f"{noise_samples!r}")
        self._joint_index = int(mount_joint.index())
        tool = mount_joint.child_body()
        self._tool_index = int(tool.index())
        self._X_TJ = mount_joint.frame_on_child().GetFixedPoseInBodyFrame()
        self._R_TJ = self._X_TJ.rotation().matrix()
        self._weight_W = np.array([0.0, 0.0, -9.81]) * tool.default_mass()
        self._sigma, self._seed, self._rate = sigma_force, seed, rate_hz
        # a stream of its own (a spawn key), apart from the per-sample (seed, k) streams
        self._table = (np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(1,)))
                       .normal(0.0, sigma_force, (int(noise_samples), 3)))
        self._table.flags.writeable = False
        self._reaction = self.DeclareAbstractInputPort(
            "reaction_forces", AbstractValue.Make([SpatialForce()]))
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()]))
        self._state = self.DeclareDiscreteState(3)
        self._dt, self._steps = float(plant_time_step), int(round(steps))
        if plant_time_step > 0:
            # the forces read at the sample instant, turned and held a plant step later;
            # the event's times are the plant's own (the same period and offset)
            self._pending = self.DeclareDiscreteState(np.full(3, np.nan))  # none read yet
            self.DeclarePeriodicDiscreteUpdateEvent(plant_time_step, 0.0, self._plant_step)
        else:
            self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._out = self.DeclareStateOutputPort("force_W", self._state)

    def get_reaction_forces_input_port(self):
        return self._reaction

    def get_body_poses_input_port(self):
        return self._poses

    def get_force_output_port(self):
        return self._out

    def true_force(self, context) -> np.ndarray:
        """Noise-free contact force on the tool, world frame."""
        return self._world_force(self._arm_on_tool(context), context)

    def _arm_on_tool(self, context) -> np.ndarray:
        """The arm's force on the tool at the mount joint, in the joint's frame Jc."""
        return self._reaction.Eval(context)[self._joint_index].translational()

    def _world_force(self, F_Jc, context) -> np.ndarray:
        """The contact force on the tool (world frame) from the arm's force on it (in Jc),
        with the tool's pose in ``context``."""
        R_WT = self._poses.Eval(context)[self._tool_index].rotation().matrix()
        f_arm_W = (R_WT @ self._R_TJ) @ F_Jc
        return -f_arm_W - self._weight_W

    def noise(self, k: int) -> np.ndarray:
        """The noise added to sample ``k`` (N, world frame)."""
        if k < self._table.shape[0]:
            return self._table[k]
        if self._sigma == 0:
            return np.zeros(3)
        return np.random.default_rng([self._seed, k]).normal(0.0, self._sigma, 3)

    def _sample(self, F_Jc, context, k: int) -> np.ndarray:
        """Sample ``k`` from the arm's force on the tool (None: not readable) and the tool's
        pose in ``context``: the contact force with its noise, zero when there is none."""
        if F_Jc is None:
            return np.zeros(3)
        try:
            f = self._world_force(F_Jc, context) + self.noise(k)
        except (RuntimeError, ValueError):
            return np.zeros(3)
        return f if math.isfinite(f[0] + f[1] + f[2]) else np.zeros(3)

    def _read(self, context):
        try:
            return self._arm_on_tool(context)
        except (RuntimeError, ValueError):
            return None

    def _update(self, context, discrete_state):
        k = int(round(context.get_time() * self._rate))
        discrete_state.set_value(self._sample(self._read(context), context, k))

    def _plant_step(self, context, discrete_state):
        m = int(round(context.get_time() / self._dt))
        r = m % self._steps
        if r > 1:
            return EventStatus.DidNothing()
        if r == 1:  # a step after a sample instant: the force read then, turned by the pose now
            F_Jc = context.get_discrete_state(self._pending).value()
            discrete_state.get_mutable_vector(self._state).SetFromVector(
                self._sample(F_Jc if np.all(np.isfinite(F_Jc)) else None, context,
                             m // self._steps))
        else:  # a sample instant: the reaction forces of the step that starts now
            F_Jc = self._read(context)
            discrete_state.get_mutable_vector(self._pending).SetFromVector(
                np.full(3, np.nan) if F_Jc is None else F_Jc)
        return EventStatus.Succeeded()
