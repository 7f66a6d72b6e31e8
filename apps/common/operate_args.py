"""The flags of one opening trial, shared by the apps open_cabinet and operate_trials."""

from __future__ import annotations

from mmlearn.apps.common.cli import nonneg_float, pos_float

__all__ = ["add_trial_args"]


def add_trial_args(ap) -> None:
    """The flags of one opening trial that open_cabinet and operate_trials share."""
    ap.add_argument("--max-time", type=pos_float, default=60.0,
                    help="simulated seconds at most")
    ap.add_argument("--sigma-pos", type=pos_float, default=None,
                    help="position noise the estimator assumes, m (default 0.05, the "
                         "thesis' value)")
    ap.add_argument("--base-noise", type=nonneg_float, default=None,
                    help="scale of the robot's base-localisation and odometry error (default "
                         "1: 0.05 m RMS, 1.1 deg, drifting; 0: base pose known exactly)")
    ap.add_argument("--perception", default="click", choices=["click", "depth"],
                    help="where the handle comes from: click = told within 2 cm; depth = "
                         "the robot looks with its head depth camera, detects the front and "
                         "derives the handle")
