"""What the hook controller is told and how it is tuned: :class:`EpcTask` (the handle and the
front's directions) and :class:`EpcConfig` (every distance, angle, force, time, gain,
threshold and count of :class:`~mmlearn.systems.articulation.epc_controller.EpcController`'s
phases, thesis Sec. 4.3)."""

import math
from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.config import param, validate_fields

__all__ = ["EpcTask", "EpcConfig"]


@dataclass
class EpcTask:
    """What the robot is told about the mechanism (world frame).

    Attributes:
        handle: estimated handle centre (e.g. clicked in a point cloud; a few cm off), m.
        normal: unit normal of the front at the handle, pointing to the robot.
        bar: unit direction of the handle bar.
        pull: initial pulling direction (unit).
        side: unit direction in the front's plane, perpendicular to the bar, on which side
            of the bar the hook's rod stays (its finger reaches behind the bar towards -side).
    """

    handle: np.ndarray
    normal: np.ndarray
    bar: np.ndarray
    pull: np.ndarray
    side: np.ndarray

    def __post_init__(self):
        for k in ("handle", "normal", "bar", "pull", "side"):
            v = np.asarray(getattr(self, k), float).reshape(-1)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(f"EpcTask.{k} must be 3 finite numbers, got {v}")
            if k != "handle":
                n = np.linalg.norm(v)
                if n < 1e-9:
                    raise ValueError(f"EpcTask.{k} must be non-zero")
                v = v / n
            setattr(self, k, v)


@dataclass
class EpcConfig:
    """Parameters of :class:`~mmlearn.systems.articulation.epc_controller.EpcController`
    (m, s, N, rad). Every field has its own entry below (``tests/test_epc_controller.py``
    checks it) and declares its unit and allowed values with ``param`` (checked by
    :meth:`validate`).

    Attributes:
        period: control period: the controller updates its equilibrium point this often,
            s.
        ik_damping: damping of the damped-least-squares IK, dimensionless.
        ik_iterations: damped-least-squares steps of the IK per call (count).
        ik_rotation_weight: weight of the rotation error against the position error in the
            IK (1 rad counts as this many m), m/rad.
        ik_position_tolerance: the IK stops once the grip point is this close to its target,
            m.
        ik_angle_tolerance: ... and the hook's orientation this close to its target, rad.
        ik_max_step: largest norm of the change of the arm's joints per IK step (the
            compliant arm follows such bounded steps smoothly), rad.
        base_weight: cost of base motion relative to arm motion in the IK while pulling,
            dimensionless.
        stance_distance: base stance (DRIVE): distance of the base in front of the handle,
            m.
        stance_side: base stance: shift of the base towards ``side`` (when ``side`` is
            horizontal), m.
        drive_speed: base speed while driving (DRIVE), m/s.
        drive_min_time: shortest base drive, however close the stance, s.
        drive_settle_time: wait after the drive before the hook approaches the handle, s.
        ready_arm_q: arm joint positions q1..q6 the arm folds into while the base drives,
            rad.
        prehook_distance: PREHOOK puts the grip point this far in front of the clicked
            handle (and ``side_offset`` beside it), m.
        side_offset: distance of the grip point beside the bar before it slides behind it, m.
        approach_time: duration of the PREHOOK approach, s.
        approach_settle_time: wait after the approach before the guarded move, s.
        depth_goal: the guarded move into the front (DEPTH) aims this far behind the
            clicked handle (plus ``depth_margin``), m.
        depth_margin: the guarded move into the front goes this much deeper than the
            clicked handle suggests before it concludes that it passed the front's edge, m.
        depth_time: duration of the guarded move over ``prehook_distance + depth_goal``
            (stretched for ``depth_margin`` to keep the speed), s.
        depth_contact_force: wrist force along the front's normal that counts as touching
            during the guarded move, N.
        bar_split_depth: a contact with the grip point more than this far in front of the
            clicked handle is the bar, not the front (the finger meets the front with the
            seat ~0.036 m behind the bar's centre, the bar ~0.044 m in front of it), m.
        bar_depth_tolerance: after a slide that missed the bar, a contact less than this far
            behind the depth where the bar was met is the bar again, m.
        edge_depth: no contact this far behind the clicked handle (plus ``depth_margin``)
            means the finger passed the front's free edge, m.
        max_retries: how often the hooking (DEPTH, SLIDE) starts over with a corrected
            side offset before it goes on regardless (count).
        retry_side_shift: change of the side offset per retry (further from the bar after
            hitting it or sliding past it, closer after passing the front's edge), m.
        retry_backoff: the hook backs out this far along the normal before a retry after
            hitting the bar or sliding past it, m.
        edge_retry_backoff: ... and this far (plus ``depth_margin``) after passing the
            front's edge, m.
        front_backoff: after touching the front, the hook backs off this far along the
            normal so the finger clears the front and the bar while it slides, m.
        slide_reach: the slide behind the bar (SLIDE) goes this far past the clicked bar
            when pulling out of the front, m.
        sliding_reach: ... and this far for a sliding door (it moves away when the rod meets
            its bar: the pull goes on in the same direction), m.
        slide_time: duration of a slide with ``sliding_reach``, s.
        slide_time_distance: a longer reach adds ``slide_time`` per this much extra reach
            (the same speed as a ``slide_time`` slide over ``side_offset + sliding_reach``
            at the defaults), m.
        slide_contact_force: side force on the hook that counts as the rod touching the bar,
            N.
        slide_near_bar: ... when the grip point is this close to the clicked bar sideways,
            m.
        slide_blocked_lag: ... or anywhere once the hook lags this far behind the commanded
            slide (the bar stops it where the click did not say), m.
        slide_reached_tolerance: the slide has reached its goal when the grip point is this
            close to it sideways, m.
        slide_settle_time: wait after the slide's duration before giving up on a contact, s.
        tip_contact_offset: a slide stopped with the hook's seat more than this beyond the
            clicked handle, on the rod's side, was stopped by the finger's tip meeting the
            handle's stem (a knob, whose head the finger cannot pass behind): the hook then
            holds the handle at its finger's tip, and that point, not the seat, is the
            handle's position (tracked, learned from and moved along the model) while
            pulling. Beyond the click's error (``click_error``, 0.02 m) and below the
            tip's distance from the seat (0.036 m), m.
        tip_handle_offset: ... the handle's centre is then taken this far beyond the
            finger's tip (the radius of a knob's stem), m.
        step: s of Eq. 4.58: equilibrium point advance per period along the model (PULL),
            m; also the progress that ends a stall.
        force_target: force kept between hook and handle perpendicular to the motion, N.
        force_gain: proportional gain of that force term, m per N per period.
        max_lead: largest distance of the equilibrium point ahead of the hook, m.
        max_turn: largest change of the hook's orientation per period, rad.
        min_model_samples: hook positions before the learned model is trusted (count).
        contact_force: hook positions count as observations of the mechanism only while the
            wrist feels at least this force, N.
        motion_window: the handle's direction of motion (for RELEASE) is taken over its
            most recent motion of at least this length, m.
        stop_force: hook force against the pull that, with the hook no longer advancing,
            means the end of the configuration range, N.
        stall_lead_fraction: the hook is also held back when the equilibrium point leads it
            by more than this fraction of ``max_lead`` (dimensionless, 0-1) ...
        stall_force_fraction: ... and the force against the pull exceeds this fraction of
            ``stop_force`` (dimensionless, 0-1).
        stall_periods: periods held back without advancing by ``step`` that end the pull
            as the end of the configuration range (count).
        slack_force: a wrist force below this means the hook is not holding the handle, N.
        slack_periods: consecutive periods below ``slack_force`` that end the pull as
            "lost the handle" (count).
        target_angle: stop when a revolute model says the mechanism turned this far, rad.
        target_distance: stop when a prismatic model says it moved this far, m. Longer
            than the drawers' travel (they end at their end stop): at sigma_pos = 0.05 m a
            door's arc reads as a line for its first ~50 deg, and a shorter target would
            stop the door there under that early prismatic model.
        max_pull_time: give up pulling after this long, s.
        release_time: duration of RELEASE, s.
        release_unload: RELEASE first moves the hook back along the handle's motion this
            far to unload the finger, m.
        release_slide_start: fraction of ``release_time`` at which the hook starts sliding
            out sideways (dimensionless, 0-1).
        release_slide: distance the hook slides out sideways, m.
        release_backoff_start: fraction of ``release_time`` at which the hook starts
            backing off from the front (dimensionless, 0-1).
        release_backoff: distance the hook backs off from the front, m.
    """

    # control and IK
    period: float = param(0.1, unit="s", gt=0)
    ik_damping: float = param(0.05, gt=0)
    ik_iterations: int = param(8, integer=True, ge=1)
    ik_rotation_weight: float = param(0.5, unit="m/rad", gt=0)
    ik_position_tolerance: float = param(1e-4, unit="m", gt=0)
    ik_angle_tolerance: float = param(1e-3, unit="rad", gt=0)
    ik_max_step: float = param(0.3, unit="rad", gt=0)
    base_weight: float = param(4.0, gt=0)
    # DRIVE
    stance_distance: float = param(0.78, unit="m", gt=0)
    stance_side: float = param(0.3, unit="m")
    drive_speed: float = param(0.5, unit="m/s", gt=0)
    drive_min_time: float = param(1.0, unit="s", gt=0)
    drive_settle_time: float = param(0.5, unit="s", ge=0)
    ready_arm_q: list[float] = param([0.0, 0.5, 0.0, 1.6, 0.0, -0.5], unit="rad",
                                     length=(1, None), elements=True, factory=True)
    # PREHOOK
    prehook_distance: float = param(0.18, unit="m", gt=0)
    side_offset: float = param(0.055, unit="m", gt=0)
    approach_time: float = param(2.0, unit="s", gt=0)
    approach_settle_time: float = param(0.5, unit="s", ge=0)
    # DEPTH (guarded move) and retries
    depth_goal: float = param(0.08, unit="m", ge=0)
    depth_margin: float = param(0.05, unit="m", ge=0)
    depth_time: float = param(2.5, unit="s", gt=0)
    depth_contact_force: float = param(3.0, unit="N", gt=0)
    bar_split_depth: float = param(0.0, unit="m")
    bar_depth_tolerance: float = param(0.03, unit="m", ge=0)
    edge_depth: float = param(0.065, unit="m", gt=0)
    max_retries: int = param(3, integer=True, ge=0)
    retry_side_shift: float = param(0.02, unit="m", gt=0)
    retry_backoff: float = param(0.05, unit="m", gt=0)
    edge_retry_backoff: float = param(0.12, unit="m", gt=0)
    front_backoff: float = param(0.018, unit="m", gt=0)
    # SLIDE
    slide_reach: float = param(0.06, unit="m", gt=0)
    sliding_reach: float = param(0.03, unit="m", gt=0)
    slide_time: float = param(1.5, unit="s", gt=0)
    slide_time_distance: float = param(0.085, unit="m", gt=0)
    slide_contact_force: float = param(3.0, unit="N", gt=0)
    slide_near_bar: float = param(0.04, unit="m", gt=0)
    slide_blocked_lag: float = param(0.02, unit="m", gt=0)
    slide_reached_tolerance: float = param(0.015, unit="m", gt=0)
    slide_settle_time: float = param(0.3, unit="s", ge=0)
    tip_contact_offset: float = param(0.025, unit="m", gt=0)
    tip_handle_offset: float = param(0.008, unit="m", ge=0)
    # PULL and stop conditions
    step: float = param(0.01, unit="m", gt=0)
    force_target: float = param(5.0, unit="N", ge=0)
    force_gain: float = param(0.005, unit="m per N per period", gt=0)
    max_lead: float = param(0.05, unit="m", gt=0)
    max_turn: float = param(0.05, unit="rad", gt=0)
    min_model_samples: int = param(15, integer=True, ge=3)
    contact_force: float = param(0.5, unit="N", ge=0)
    motion_window: float = param(0.03, unit="m", gt=0)
    stop_force: float = param(35.0, unit="N", gt=0)
    stall_lead_fraction: float = param(0.9, gt=0, le=1)
    stall_force_fraction: float = param(0.3, gt=0)
    stall_periods: int = param(8, integer=True, ge=1)
    slack_force: float = param(1.0, unit="N", gt=0)
    slack_periods: int = param(15, integer=True, ge=1)
    target_angle: float = param(math.radians(85), unit="rad", gt=0)
    target_distance: float = param(0.65, unit="m", gt=0)
    max_pull_time: float = param(25.0, unit="s", gt=0)
    # RELEASE (and back-off)
    release_time: float = param(2.0, unit="s", gt=0)
    release_unload: float = param(0.015, unit="m", ge=0)
    release_slide_start: float = param(0.25, gt=0, lt=1)
    release_slide: float = param(0.12, unit="m", ge=0)
    release_backoff_start: float = param(0.65, gt=0, lt=1)
    release_backoff: float = param(0.15, unit="m", ge=0)

    def __post_init__(self):
        self.validate()

    def validate(self):
        """Raise ValueError naming the first field whose value would break the controller.

        Runs on construction; ``yaml_load_typed`` sets the fields of a default-constructed
        config, so the controller validates its config again.
        """
        validate_fields(self)
        if not self.release_slide_start < self.release_backoff_start:
            raise ValueError(
                "EpcConfig: release_slide_start and release_backoff_start must satisfy "
                f"0 < release_slide_start < release_backoff_start < 1, got "
                f"{self.release_slide_start!r}, {self.release_backoff_start!r}")
