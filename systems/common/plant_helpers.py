"""Small LeafSystems the scene diagrams need around a MultibodyPlant."""

from __future__ import annotations

import numpy as np

from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import BasicVector, Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import MatrixGain


class GravityCompensation(Diagram):
    """Feed-forward actuation that cancels gravity on one model instance's actuated joints.

    Drake's ``InverseDynamics`` in ``kGravityCompensation`` mode (it keeps its plant context
    in a cache entry of its own context) followed by a ``MatrixGain`` that picks the
    instance's actuated velocities.

    .. pydrake_system::

        name: GravityCompensation
        input_ports:
        - state
        output_ports:
        - actuation

    ``state`` is the plant's full state [q; v]; ``actuation`` is ordered like the plant's
    actuation input port for ``model_instance`` (increasing JointActuatorIndex), N*m or N.
    """

    def __init__(self, *, plant, model_instance):
        super().__init__()
        v_index = [plant.get_joint_actuator(a).joint().velocity_start()
                   for a in plant.GetJointActuatorIndices(model_instance)]
        S = np.zeros((len(v_index), plant.num_velocities()))
        S[np.arange(len(v_index)), v_index] = 1.0
        builder = DiagramBuilder()
        idyn = builder.AddNamedSystem("inverse_dynamics", InverseDynamics(
            plant=plant, mode=InverseDynamics.InverseDynamicsMode.kGravityCompensation))
        select = builder.AddNamedSystem("select_actuated", MatrixGain(S))
        builder.Connect(idyn.get_output_port_generalized_force(), select.get_input_port())
        builder.ExportInput(idyn.get_input_port_estimated_state(), "state")
        builder.ExportOutput(select.get_output_port(), "actuation")
        builder.BuildInto(self)
        self.set_name("gravity_compensation")

    def get_state_input_port(self):
        return self.get_input_port(0)

    def get_actuation_output_port(self):
        return self.get_output_port(0)


class StateForceSystem(LeafSystem):
    """Base of the stateless systems that map the plant's full state (q, v) to generalized
    forces for its ``applied_generalized_force`` input: the ``state`` input and the
    ``generalized_force`` output (nv,), computed by the subclass' ``_calc(context, output)``
    (declared in ``__init__`` by :meth:`_declare_state_force_ports`).

    .. pydrake_system::

        name: StateForceSystem
        input_ports:
        - state
        output_ports:
        - generalized_force
    """

    def _declare_state_force_ports(self, num_positions: int, num_velocities: int) -> None:
        self._state = self.DeclareVectorInputPort("state", num_positions + num_velocities)
        self._out = self.DeclareVectorOutputPort(
            "generalized_force", BasicVector(num_velocities), self._calc,
            prerequisites_of_calc={self._state.ticket()})

    def get_state_input_port(self):
        return self._state

    def get_generalized_force_output_port(self):
        return self._out


#: the speed over which the scenes' joint friction builds up (``tanh(v / STICTION_VELOCITY)``),
#: m/s or rad/s: :class:`JointFriction`'s default, a revolute mechanism's ``DoorHinge`` and
#: the dynamics monitor's model of it
STICTION_VELOCITY = 0.02


class JointFriction(StateForceSystem):
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
                 v_stiction: float = STICTION_VELOCITY):
        super().__init__()
        if v_stiction <= 0:
            raise ValueError("JointFriction: v_stiction must be > 0")
        self._nq, self._nv = num_positions, num_velocities
        self._idx = np.array(list(joints.keys()), dtype=int)
        self._state_idx = num_positions + self._idx  # the joints' velocities in [q; v]
        self._mu = np.array(list(joints.values()), dtype=float)
        if np.any(self._mu < 0):
            raise ValueError("JointFriction: friction coefficients must be >= 0")
        self._vs = v_stiction
        self._declare_state_force_ports(num_positions, num_velocities)

    def _calc(self, context, output):
        # evaluated at every plant step: write into the output's own vector
        tau = output.get_mutable_value()
        tau[:] = 0.0
        tau[self._idx] = -self._mu * np.tanh(self._state.Eval(context)[self._state_idx]
                                             / self._vs)
