"""WristForceSensor: the force the environment exerts on the end effector, as a wrist
force-torque sensor between the last link and the tool would report it."""

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialForce
from pydrake.systems.framework import LeafSystem


class WristForceSensor(LeafSystem):
    """Measures the external (contact) force on a tool welded to the arm.

    From the plant's joint reaction forces at the tool's mount joint (the force of the arm
    on the tool) and the tool's weight: in quasi-static conditions
    F_contact = -F_arm_on_tool - m_tool * g. Gaussian noise of ``sigma_force`` N per axis
    is added, drawn from (seed, sample index) so runs are reproducible; the sample is held
    between updates at ``rate_hz``.

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
                 seed: int = 0):
        super().__init__()
        if sigma_force < 0 or not np.isfinite(sigma_force):
            raise ValueError(f"WristForceSensor: sigma_force must be >= 0, got {sigma_force}")
        if not rate_hz > 0:
            raise ValueError(f"WristForceSensor: rate_hz must be > 0, got {rate_hz}")
        self._joint_index = int(mount_joint.index())
        tool = mount_joint.child_body()
        self._tool_index = int(tool.index())
        self._X_TJ = mount_joint.frame_on_child().GetFixedPoseInBodyFrame()
        self._weight_W = np.array([0.0, 0.0, -9.81]) * tool.default_mass()
        self._sigma, self._seed, self._rate = sigma_force, seed, rate_hz
        self._reaction = self.DeclareAbstractInputPort(
            "reaction_forces", AbstractValue.Make([SpatialForce()]))
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()]))
        self._state = self.DeclareDiscreteState(3)
        self.DeclarePeriodicDiscreteUpdateEvent(1.0 / rate_hz, 0.0, self._update)
        self._out = self.DeclareStateOutputPort("force_W", self._state)

    def get_reaction_forces_input_port(self):
        return self._reaction

    def get_body_poses_input_port(self):
        return self._poses

    def get_force_output_port(self):
        return self._out

    def true_force(self, context) -> np.ndarray:
        """Noise-free contact force on the tool, world frame."""
        F_Jc = self._reaction.Eval(context)[self._joint_index]  # arm on tool, in Jc
        X_WT = self._poses.Eval(context)[self._tool_index]
        R_WJ = X_WT.rotation().matrix() @ self._X_TJ.rotation().matrix()
        f_arm_W = R_WJ @ F_Jc.translational()
        return -f_arm_W - self._weight_W

    def _update(self, context, discrete_state):
        k = int(round(context.get_time() * self._rate))
        noise = np.random.default_rng([self._seed, k]).normal(0.0, self._sigma, 3)
        try:
            f = self.true_force(context) + noise
        except (RuntimeError, ValueError):
            f = np.zeros(3)
        if not np.all(np.isfinite(f)):
            f = np.zeros(3)
        discrete_state.set_value(f)
