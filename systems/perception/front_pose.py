"""TrueFrontPose: the ground-truth pose of a moving cabinet front, from its joint value."""

from __future__ import annotations

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, LeafSystem

from mmlearn.models.perception.motion import FrontJointKinematics
from mmlearn.models.perception.fronts import FrontRectangle

__all__ = ["TrueFrontPose"]


class TrueFrontPose(LeafSystem):
    """The true pose of a front's outer face (to score detections against).

    .. pydrake_system::

        name: TrueFrontPose
        input_ports:
        - positions
        output_ports:
        - X_WR
        - front
        - joint_value

    ``positions`` is the plant's generalized position vector (size ``num_positions``);
    ``X_WR`` (``RigidTransform``) is the centre of the front's outer face with x along the
    width, y along the height and z the outward normal (the
    :class:`~mmlearn.models.perception.fronts.FrontRectangle` convention); ``front`` is the same as a
    ``FrontRectangle`` with the true width and height (precision = recall = 1);
    ``joint_value`` is the front's joint value (rad or m).

    Args:
        kinematics: the front's :class:`FrontJointKinematics` (world frame).
        position_index: index of the front's joint in ``positions``.
        num_positions: size of the ``positions`` input.
    """

    def __init__(self, *, kinematics: FrontJointKinematics, position_index: int,
                 num_positions: int):
        super().__init__()
        if not 0 <= int(position_index) < int(num_positions):
            raise ValueError(f"TrueFrontPose: position_index {position_index} outside "
                             f"[0, {num_positions})")
        self._kin = kinematics
        self._i = int(position_index)
        self._q = self.DeclareVectorInputPort("positions", int(num_positions))
        self._X = self.DeclareAbstractOutputPort(
            "X_WR", lambda: AbstractValue.Make(RigidTransform()), self._calc_X)
        self._front = self.DeclareAbstractOutputPort(
            "front", lambda: AbstractValue.Make(
                FrontRectangle(np.eye(4), kinematics.width, kinematics.height)),
            self._calc_front)
        self._jv = self.DeclareVectorOutputPort("joint_value", 1, self._calc_q)

    def get_positions_input_port(self):
        return self._q

    def get_X_WR_output_port(self):
        return self._X

    def get_front_output_port(self):
        return self._front

    def get_joint_value_output_port(self):
        return self._jv

    @property
    def kinematics(self) -> FrontJointKinematics:
        return self._kin

    def _X_WR(self, context) -> np.ndarray:
        return self._kin.X_WR(float(self._q.Eval(context)[self._i]))

    def _calc_X(self, context, output):
        output.set_value(RigidTransform(self._X_WR(context)))

    def _calc_front(self, context, output):
        output.set_value(FrontRectangle(self._X_WR(context), self._kin.width, self._kin.height))

    def _calc_q(self, context, output: BasicVector):
        output.SetAtIndex(0, float(self._q.Eval(context)[self._i]))
