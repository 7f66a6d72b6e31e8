"""KinematicBodyPoses: the body poses of a plant at given generalized positions (playback)."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.framework import LeafSystem, ValueProducer

__all__ = ["KinematicBodyPoses"]


class KinematicBodyPoses(LeafSystem):
    """The world poses of all bodies of ``plant`` at the positions on the input port: the
    ``body_poses`` a :class:`~mmlearn.systems.common.marker_sensor.MarkerSensor` reads, for
    diagrams that play configurations back kinematically (no dynamics: the plant is used for
    its kinematics only, e.g. beside a ``MultibodyPositionToGeometryPose`` that poses the
    same plant's geometry in a SceneGraph).

    .. pydrake_system::

        name: KinematicBodyPoses
        input_ports:
        - positions
        output_ports:
        - body_poses

    ``positions`` is the plant's generalized position vector (size ``num_positions()``; a
    quaternion of a free body is normalised before use; a non-finite entry gives identity
    poses, so a bad sample never stops a simulation). ``body_poses`` is a list of
    ``RigidTransform`` indexed by ``BodyIndex`` (like ``MultibodyPlant``'s port).

    Args:
        plant: a finalized MultibodyPlant (kept by reference: keep it alive).
    """

    def __init__(self, *, plant):
        super().__init__()
        if not plant.is_finalized():
            raise ValueError("KinematicBodyPoses: the plant must be finalized")
        self._plant = plant
        self._n = plant.num_positions()
        self._nb = plant.num_bodies()
        # unit-quaternion blocks of free bodies (w x y z)
        self._quats = [plant.get_body(b).floating_positions_start()
                       for b in plant.GetFloatingBaseBodies()]
        self._q = self.DeclareVectorInputPort("positions", self._n)
        # the plant context at the input positions lives in a cache entry of this system's
        # context (no member context is mutated)
        self._ctx = self.DeclareCacheEntry(
            "plant_context",
            ValueProducer(allocate=lambda: AbstractValue.Make(plant.CreateDefaultContext()),
                          calc=self._calc_context),
            {self._q.ticket()})
        self._out = self.DeclareAbstractOutputPort(
            "body_poses", lambda: AbstractValue.Make([RigidTransform()] * self._nb),
            self._calc_poses, {self._ctx.ticket()})

    def get_positions_input_port(self):
        return self._q

    def get_body_poses_output_port(self):
        return self._out

    def _calc_context(self, context, abstract_value):
        q = np.array(self._q.Eval(context), float)
        for s in self._quats:
            nrm = np.linalg.norm(q[s:s + 4])
            q[s:s + 4] = q[s:s + 4] / nrm if nrm > 1e-12 else [1.0, 0.0, 0.0, 0.0]
        ctx = abstract_value.get_mutable_value()
        if np.all(np.isfinite(q)):
            self._plant.SetPositions(ctx, q)

    def _calc_poses(self, context, output):
        q = self._q.Eval(context)
        if not np.all(np.isfinite(q)):
            output.set_value([RigidTransform()] * self._nb)
            return
        ctx = self._ctx.Eval(context)
        output.set_value([self._plant.EvalBodyPoseInWorld(ctx, self._plant.get_body(BodyIndex(i)))
                          for i in range(self._nb)])
