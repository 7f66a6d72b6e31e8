"""GraspAttachment: a documented grasp model that holds an object between closed fingers.

Simulating a cup held by friction between two angular fingers needs fine contact
geometry and small time steps; the imitation experiments (thesis ch. 8) are about *where*
the hand goes and *when* it closes, so the grasp is modelled instead:

* **capture**: when the commanded finger angle is below ``closed_below`` (the gripper is
  closed) and the object's grasp point (``p_object`` in the object's body frame) is within
  ``capture_radius`` of the tool centre point, the object is attached; the point of the
  object that coincides with the TCP at that moment, and the object's world orientation,
  are remembered (discrete state);
* **holding**: while attached, a spring-damper force (``stiffness`` N/m, critically
  damped for the object's mass unless ``damping`` is given) pulls that object point to
  the TCP, plus the object's weight as feed-forward (no sag); a rotational spring-damper
  (``rot_stiffness`` N*m/rad, critically damped) keeps the object's world orientation at
  the one it had when captured (a wrist that keeps a cup level: the arm's six joints are
  commanded for the hand's position only). The opposite force and torque act on the hand
  body, so momentum is conserved;
* **release**: as soon as the gripper opens (finger angle >= ``closed_below``), or when
  the object slips: its grasp point more than ``slip_distance`` from the TCP (the spring
  force is also limited to ``max_force``, so a hand that jerks away cannot make the
  simulation diverge).

The forces go to the plant's ``applied_spatial_force`` input as
``ExternallyAppliedSpatialForce`` values.
"""

from __future__ import annotations

import math

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce, SpatialVelocity
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem


class GraspAttachment(LeafSystem):
    """Spring-damper grasp of one object by the hand while the gripper is closed.

    .. pydrake_system::

        name: GraspAttachment
        input_ports:
        - body_poses
        - body_spatial_velocities
        - gripper_angle
        output_ports:
        - spatial_forces
        - attached

    ``body_poses`` / ``body_spatial_velocities`` take the plant's outputs of those names;
    ``gripper_angle`` is the commanded finger angle, rad (0 = closed). ``spatial_forces``
    is a list of ``ExternallyAppliedSpatialForce`` (empty while nothing is held) for the
    plant's ``applied_spatial_force`` input; ``attached`` is 1 while the object is held.
    """

    def __init__(self, *, plant, hand_body, p_tcp, object_body, p_object=(0.0, 0.0, 0.0),
                 capture_radius: float = 0.06, closed_below: float = 0.3,
                 stiffness: float = 400.0, damping: float | None = None,
                 rot_stiffness: float = 1.0, period: float = 0.01,
                 max_force: float = 40.0, slip_distance: float = 0.08):
        """
        Args:
            plant: the finalized MultibodyPlant.
            hand_body: the body (or its name) carrying the tool centre point.
            p_tcp: tool centre point in the hand body's frame, m.
            object_body: the body (or its name) that can be grasped.
            p_object: the object's grasp reference point in its body frame, m.
            capture_radius: largest TCP-to-grasp-point distance at which closing the
                gripper captures the object, m.
            closed_below: finger angle under which the gripper counts as closed, rad.
            stiffness: translational spring, N/m.
            damping: translational damper, N*s/m (None = critical for the object's mass).
            rot_stiffness: rotational spring keeping the captured orientation, N*m/rad
                (its damper is critical for the object's largest principal moment).
            period: how often capture and release are decided, s.
            max_force: largest spring-damper force, N.
            slip_distance: TCP-to-grasp-point distance at which a held object slips out, m.
        """
        super().__init__()
        for name, v in (("capture_radius", capture_radius), ("stiffness", stiffness),
                        ("rot_stiffness", rot_stiffness), ("period", period),
                        ("max_force", max_force), ("slip_distance", slip_distance)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"GraspAttachment: {name} must be a finite number > 0, "
                                 f"got {v!r}")
        hand = plant.GetBodyByName(hand_body) if isinstance(hand_body, str) else hand_body
        obj = plant.GetBodyByName(object_body) if isinstance(object_body, str) else object_body
        self._hand = int(hand.index())
        self._obj = int(obj.index())
        self._p_tcp = np.asarray(p_tcp, float).reshape(3)
        self._p_obj = np.asarray(p_object, float).reshape(3)
        self._radius = float(capture_radius)
        self._max_force = float(max_force)
        self._slip = float(slip_distance)
        self._closed_below = float(closed_below)
        mass = float(obj.default_mass())
        if not (math.isfinite(mass) and mass > 0):
            raise ValueError(f"GraspAttachment: body {obj.name()!r} has no positive mass")
        self._mass = mass
        self._k = float(stiffness)
        self._d = float(damping) if damping is not None else 2.0 * math.sqrt(self._k * mass)
        inertia = obj.default_rotational_inertia().CopyToFullMatrix3()
        i_max = float(np.max(np.linalg.eigvalsh(inertia))) if np.all(np.isfinite(inertia)) \
            else mass * 0.01
        self._kr = float(rot_stiffness)
        self._dr = 2.0 * math.sqrt(self._kr * max(i_max, 1e-9))
        g = plant.gravity_field().gravity_vector() if hasattr(plant, "gravity_field") \
            else np.array([0.0, 0.0, -9.81])
        self._g = np.asarray(g, float)
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()]))
        self._vels = self.DeclareAbstractInputPort(
            "body_spatial_velocities", AbstractValue.Make([SpatialVelocity()]))
        self._grip = self.DeclareVectorInputPort("gripper_angle", 1)
        # [attached, grasp point in object frame (3), captured R_WO (9)]
        self._s = self.DeclareDiscreteState(13)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._out = self.DeclareAbstractOutputPort(
            "spatial_forces", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
            self._calc_forces,
            {self.discrete_state_ticket(self._s), self._poses.ticket(), self._vels.ticket()})
        self._out_att = self.DeclareVectorOutputPort(
            "attached", BasicVector(1),
            lambda c, o: o.SetAtIndex(0, c.get_discrete_state(self._s).GetAtIndex(0)),
            prerequisites_of_calc={self.discrete_state_ticket(self._s)})

    def get_body_poses_input_port(self):
        return self._poses

    def get_body_spatial_velocities_input_port(self):
        return self._vels

    def get_gripper_angle_input_port(self):
        return self._grip

    def get_spatial_forces_output_port(self):
        return self._out

    def get_attached_output_port(self):
        return self._out_att

    def tcp_and_grasp_point(self, context):
        """(TCP, the object's grasp reference point), world, m."""
        X = self._poses.Eval(context)
        return X[self._hand] @ self._p_tcp, X[self._obj] @ self._p_obj

    def _update(self, context, discrete_state):
        s = context.get_discrete_state(self._s).get_value().copy()
        angle = float(self._grip.Eval(context)[0])
        closed = math.isfinite(angle) and angle < self._closed_below
        if not closed:
            s[0] = 0.0
        elif s[0] == 1.0:
            X = self._poses.Eval(context)
            tcp = X[self._hand] @ self._p_tcp
            if not np.linalg.norm(tcp - X[self._obj] @ s[1:4]) <= self._slip:
                s[0] = 0.0  # slipped out (or a pose that cannot be computed)
        elif s[0] == 0.0:
            X = self._poses.Eval(context)
            X_WH, X_WO = X[self._hand], X[self._obj]
            tcp = X_WH @ self._p_tcp
            if np.linalg.norm(tcp - X_WO @ self._p_obj) <= self._radius:
                s[0] = 1.0
                s[1:4] = X_WO.inverse() @ tcp
                s[4:13] = X_WO.rotation().matrix().ravel()
        discrete_state.set_value(self._s, s)
        return EventStatus.Succeeded()

    def _calc_forces(self, context, output):
        s = context.get_discrete_state(self._s).get_value()
        if s[0] == 0.0:
            output.set_value([])
            return
        X = self._poses.Eval(context)
        V = self._vels.Eval(context)
        X_WH, X_WO = X[self._hand], X[self._obj]
        V_H, V_O = V[self._hand], V[self._obj]
        p_OG = s[1:4]
        tcp = X_WH @ self._p_tcp
        p_G = X_WO @ p_OG
        # velocities of the TCP and of the object's grasp point in the world
        r_H = X_WH.rotation().matrix() @ self._p_tcp
        r_O = X_WO.rotation().matrix() @ p_OG
        v_tcp = V_H.translational() + np.cross(V_H.rotational(), r_H)
        v_G = V_O.translational() + np.cross(V_O.rotational(), r_O)
        f = self._k * (tcp - p_G) + self._d * (v_tcp - v_G)
        nf = float(np.linalg.norm(f))
        if nf > self._max_force:
            f *= self._max_force / nf
        f = f - self._mass * self._g
        R_des = RotationMatrix(s[4:13].reshape(3, 3))
        aa = (R_des @ X_WO.rotation().inverse()).ToAngleAxis()
        tau = self._kr * aa.axis() * aa.angle() - self._dr * (V_O.rotational()
                                                              - V_H.rotational())
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(tau))):
            output.set_value([])  # a state that cannot be computed: let go, never crash
            return
        f_obj = ExternallyAppliedSpatialForce()
        f_obj.body_index = self._body_index(self._obj)
        f_obj.p_BoBq_B = p_OG
        f_obj.F_Bq_W = SpatialForce(tau, f)
        f_hand = ExternallyAppliedSpatialForce()
        f_hand.body_index = self._body_index(self._hand)
        f_hand.p_BoBq_B = self._p_tcp
        f_hand.F_Bq_W = SpatialForce(-tau, -f)
        output.set_value([f_obj, f_hand])

    @staticmethod
    def _body_index(i):
        from pydrake.multibody.tree import BodyIndex

        return BodyIndex(i)
