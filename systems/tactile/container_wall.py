"""ContainerWallForce: the content of a squeezed container pushing back on its two walls."""

from __future__ import annotations

import numpy as np

from mmlearn.models.tactile.containers import ContainerInstance, wall_forces
from mmlearn.systems.common.plant_helpers import StateForceSystem

__all__ = ["ContainerWallForce"]


class ContainerWallForce(StateForceSystem):
    """Generalized forces of a container's content (gas law of the closed headspace,
    hydrostatic head and flow resistance of the liquid) on its two wall joints, from the
    squeeze-volume model :func:`mmlearn.models.tactile.containers.wall_forces`, for the plant's
    ``applied_generalized_force`` input. The shell's own linear spring is a
    ``PrismaticSpring`` and the empty wall's damping the joint's damping (both in the plant).

    .. pydrake_system::

        name: ContainerWallForce
        input_ports:
        - state
        output_ports:
        - generalized_force

    ``state``: the plant's full state (q, v); ``generalized_force``: (nv,) N on the two wall
    joints (inward positive), 0 elsewhere. Stateless (a pure function of the input), so the
    discrete plant applies it explicitly from the previous step's state. At the plant's 1 ms
    step and probing forces up to 23 N the content's stiffness on one wall is at most
    ~3.2e3 N/m (a full closed water bottle, whose wall carries 0.32 kg of added liquid mass)
    and omega * dt at most 0.8 (the 4 g wall of an empty closed water bottle, 2.6e3 N/m),
    inside the explicit limit of 2 even before the finger in contact adds its mass. The flow
    damping ``R_liq dV'^2`` reaches c dt / m = 3.7 on the 28 g wall of a full open can at
    23 N (0.9 for the Odwalla bottle; measured over 20 instances per class and state), past
    the explicit limit for a free wall, but it only grows with the squeeze, i.e. while a
    finger presses the wall: simulated at 23 N the can's wall velocity changes sign once
    (the impact) before the fingers release, with small changes from step to step.

    Args:
        container: the instance (its ``closed``, ``gas_volume``, ``shell_compliance``,
            ``squeeze_length``, ``neck_area``, ``liquid_resistance``, ``fill``).
        num_positions, num_velocities: the plant's nq and nv.
        q_index, v_index: the two wall joints' position and velocity indices (left, right)
            in the plant's state.
    """

    def __init__(self, *, container: ContainerInstance, num_positions: int,
                 num_velocities: int, q_index, v_index):
        super().__init__()
        if not isinstance(container, ContainerInstance):
            raise TypeError(f"ContainerWallForce: container must be a ContainerInstance, got "
                            f"{type(container).__name__}")
        qi = np.asarray(q_index, dtype=int)
        vi = np.asarray(v_index, dtype=int)
        if qi.shape != (2,) or vi.shape != (2,):
            raise ValueError(f"ContainerWallForce: q_index and v_index must hold 2 indices, "
                             f"got {q_index!r} and {v_index!r}")
        if qi.min() < 0 or qi.max() >= num_positions or vi.min() < 0 \
                or vi.max() >= num_velocities:
            raise ValueError(f"ContainerWallForce: indices {q_index!r} / {v_index!r} outside "
                             f"nq = {num_positions}, nv = {num_velocities}")
        # validate the model's numbers once (raises on a bad instance)
        wall_forces(container, np.zeros(2), np.zeros(2))
        self._inst, self._nq, self._nv, self._qi, self._vi = (container, int(num_positions),
                                                              int(num_velocities), qi, vi)
        self._declare_state_force_ports(num_positions, num_velocities)

    def _calc(self, context, output):
        x = self._state.Eval(context)
        q, v = x[self._qi], x[self._nq + self._vi]
        tau = np.zeros(self._nv)
        f = wall_forces(self._inst, q, v)
        # a non-finite reading (e.g. a diverging step) must not kill the simulation
        tau[self._vi] = np.where(np.isfinite(f), f, 0.0)
        output.SetFromVector(tau)
