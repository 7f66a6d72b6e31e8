"""Failures of the arm that a body-schema learner is not told about (thesis Sec. 3.4.3).

Two pieces:

* :class:`JointBlocker` (a LeafSystem between the command source and the scene's
  ``command`` port): a *blocked joint* stops following its command; the PD set point of that
  joint is frozen at the value it had when it was blocked. The learner still sees the
  original command.
* :class:`PlantFailures` (a helper on the plant of a scene built with
  ``SceneConfig(failure_joints=True)``): the hidden, unactuated joints of the arm are kept
  locked (``Joint.Lock`` on the context) and moved to a failure's value while a simulation
  is paused between ``AdvanceTo`` calls: a *bent link* (joint ``<part>_bend``, rad) and a
  *tool change* (joints ``tool_length``, m, and ``tool_angle``, rad).

Both are switchable during a run (call their methods on the root context between
``Simulator.AdvanceTo`` calls; ``Simulator.Initialize`` is not needed again).
"""

from __future__ import annotations

import numpy as np

from pydrake.systems.framework import BasicVector, LeafSystem

__all__ = ["JointBlocker", "PlantFailures"]


class JointBlocker(LeafSystem):
    """Passes a command vector through, except for blocked entries, which hold the value
    they had when they were blocked.

    .. pydrake_system::

        name: JointBlocker
        input_ports:
        - command
        output_ports:
        - command

    Args:
        size: length of the command vector (>= 1).

    State (discrete, 2 * size): [blocked flags (0/1); frozen values]. Use
    :meth:`block` / :meth:`unblock` with this system's context (or the root context).
    """

    def __init__(self, *, size: int):
        super().__init__()
        if int(size) < 1:
            raise ValueError(f"JointBlocker: size must be >= 1, got {size}")
        self._n = int(size)
        self._in = self.DeclareVectorInputPort("command", self._n)
        self._state = self.DeclareDiscreteState(2 * self._n)
        self._out = self.DeclareVectorOutputPort(
            "command", BasicVector(self._n), self._calc,
            prerequisites_of_calc={self._in.ticket(), self.discrete_state_ticket(self._state)})

    def get_command_input_port(self):
        return self._in

    def get_command_output_port(self):
        return self._out

    def _ctx(self, context):
        try:
            return self.GetMyMutableContextFromRoot(context)
        except (RuntimeError, ValueError):
            return context

    def block(self, context, index: int, value: float | None = None) -> None:
        """Block command entry ``index`` at ``value`` (default: its current command)."""
        ctx = self._ctx(context)
        if not 0 <= int(index) < self._n:
            raise ValueError(f"JointBlocker: index must be in [0, {self._n}), got {index}")
        x = ctx.get_discrete_state(self._state).get_value().copy()
        if value is None:
            value = float(self._in.Eval(ctx)[index]) if self._in.HasValue(ctx) else 0.0
        x[index], x[self._n + index] = 1.0, float(value)
        ctx.SetDiscreteState(self._state, x)

    def unblock(self, context, index: int | None = None) -> None:
        """Unblock entry ``index`` (None = all)."""
        ctx = self._ctx(context)
        x = ctx.get_discrete_state(self._state).get_value().copy()
        if index is None:
            x[: self._n] = 0.0
        else:
            x[int(index)] = 0.0
        ctx.SetDiscreteState(self._state, x)

    def blocked(self, context) -> dict:
        """{index: frozen value} of the blocked entries."""
        x = self._ctx(context).get_discrete_state(self._state).get_value()
        return {i: float(x[self._n + i]) for i in range(self._n) if x[i] > 0.5}

    def _calc(self, context, output):
        u = self._in.Eval(context)
        x = context.get_discrete_state(self._state).get_value()
        output.SetFromVector(np.where(x[: self._n] > 0.5, x[self._n:], u))


class PlantFailures:
    """Hidden-joint failures of an arm built with ``failure_joints=True``.

    Args:
        plant: the finalised MultibodyPlant.
        model_instance: the arm's model instance.

    Raises ValueError when the arm has no hidden failure joints.
    """

    def __init__(self, *, plant, model_instance):
        self._plant = plant
        names = [plant.get_joint(j).name() for j in plant.GetJointIndices(model_instance)]
        bends = [n for n in names if n.endswith("_bend")]
        if not bends or "tool_length" not in names or "tool_angle" not in names:
            raise ValueError("PlantFailures: the arm has no hidden failure joints (build the "
                             "scene with SceneConfig(failure_joints=True))")
        self.bend_joint = plant.GetJointByName(bends[0], model_instance)
        self.tool_length_joint = plant.GetJointByName("tool_length", model_instance)
        self.tool_angle_joint = plant.GetJointByName("tool_angle", model_instance)
        self.bent_part = bends[0].removesuffix("_bend")

    @property
    def joints(self):
        return [self.bend_joint, self.tool_length_joint, self.tool_angle_joint]

    def _set(self, root_context, values) -> None:
        ctx = self._plant.GetMyMutableContextFromRoot(root_context)
        q = self._plant.GetPositions(ctx)
        v = self._plant.GetVelocities(ctx)
        for j, val in zip(self.joints, values):
            if val is not None:
                if not np.isfinite(val):
                    raise ValueError(f"PlantFailures: {j.name()} value must be finite")
                q[j.position_start()] = float(val)
            v[j.velocity_start()] = 0.0
        self._plant.SetPositions(ctx, q)
        self._plant.SetVelocities(ctx, v)
        for j in self.joints:
            j.Lock(ctx)

    def lock(self, root_context) -> None:
        """Lock the hidden joints where they are (call once before simulating)."""
        self._set(root_context, [None, None, None])

    def reset(self, root_context) -> None:
        """The intact arm: no bend, the original tool."""
        self._set(root_context, [0.0, 0.0, 0.0])

    def bend_link(self, root_context, angle: float = np.pi / 4) -> None:
        """Bend the middle link by ``angle`` rad (about the link's x axis)."""
        self._set(root_context, [angle, None, None])

    def unbend(self, root_context) -> None:
        self._set(root_context, [0.0, None, None])

    def change_tool(self, root_context, length: float = 0.10, angle: float = np.pi / 6) -> None:
        """A different tool: ``length`` m longer, tilted by ``angle`` rad about y."""
        self._set(root_context, [None, length, angle])

    def reset_tool(self, root_context) -> None:
        self._set(root_context, [None, 0.0, 0.0])

    def state(self, root_context) -> dict:
        ctx = self._plant.GetMyContextFromRoot(root_context)
        q = self._plant.GetPositions(ctx)
        return {j.name(): float(q[j.position_start()]) for j in self.joints}
