"""Small LeafSystems the scene diagrams need around a MultibodyPlant."""

from __future__ import annotations

import numpy as np

from pydrake.systems.framework import BasicVector, LeafSystem


class GravityCompensation(LeafSystem):
    """Feed-forward actuation that cancels gravity on one model instance's actuated joints.

    .. pydrake_system::

        name: GravityCompensation
        input_ports:
        - state
        output_ports:
        - actuation

    ``state`` is the plant's full state [q; v]; ``actuation`` is ordered like the plant's
    actuation input port for ``model_instance`` (increasing JointActuatorIndex).
    """

    def __init__(self, *, plant, model_instance):
        super().__init__()
        self._plant = plant
        self._ctx = plant.CreateDefaultContext()
        self._v_index = np.array([
            plant.get_joint_actuator(a).joint().velocity_start()
            for a in plant.GetJointActuatorIndices(model_instance)], dtype=int)
        nx = plant.num_positions() + plant.num_velocities()
        self._nq = plant.num_positions()
        self._state = self.DeclareVectorInputPort("state", nx)
        self._out = self.DeclareVectorOutputPort(
            "actuation", BasicVector(len(self._v_index)), self._calc)

    def get_state_input_port(self):
        return self._state

    def get_actuation_output_port(self):
        return self._out

    def _calc(self, context, output):
        x = self._state.Eval(context)
        self._plant.SetPositions(self._ctx, x[: self._nq])
        tau_g = self._plant.CalcGravityGeneralizedForces(self._ctx)
        output.SetFromVector(-tau_g[self._v_index])


class JointFriction(LeafSystem):
    """Regularised Coulomb friction on chosen joints, as generalized forces.

    tau_i = -mu_i * tanh(v_i / v_stiction), for the plant's ``applied_generalized_force``
    input. ``joints`` maps joint velocity indices to mu (N*m for revolute, N for prismatic).

    .. pydrake_system::

        name: JointFriction
        input_ports:
        - state
        output_ports:
        - generalized_force
    """

    def __init__(self, *, num_positions: int, num_velocities: int, joints: dict[int, float],
                 v_stiction: float = 0.02):
        super().__init__()
        if v_stiction <= 0:
            raise ValueError("JointFriction: v_stiction must be > 0")
        self._nq, self._nv = num_positions, num_velocities
        self._idx = np.array(list(joints.keys()), dtype=int)
        self._mu = np.array(list(joints.values()), dtype=float)
        if np.any(self._mu < 0):
            raise ValueError("JointFriction: friction coefficients must be >= 0")
        self._vs = v_stiction
        self._state = self.DeclareVectorInputPort("state", num_positions + num_velocities)
        self._out = self.DeclareVectorOutputPort(
            "generalized_force", BasicVector(num_velocities), self._calc)

    def get_state_input_port(self):
        return self._state

    def get_generalized_force_output_port(self):
        return self._out

    def _calc(self, context, output):
        v = self._state.Eval(context)[self._nq:]
        tau = np.zeros(self._nv)
        tau[self._idx] = -self._mu * np.tanh(v[self._idx] / self._vs)
        output.SetFromVector(tau)
