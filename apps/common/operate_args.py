"""The flags of one opening trial, shared by the apps open_cabinet and operate_trials."""

from __future__ import annotations

from mmlearn.apps.common.cli import nonneg_float, pos_float

__all__ = ["add_trial_args", "add_model_args", "load_model_args"]


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


def add_model_args(ap) -> None:
    """The flags that open a joint of the user's own model file (SDFormat or URDF) instead
    of one of the project's mechanisms, in their own group."""
    g = ap.add_argument_group(
        "your own model", "open a joint of your own SDFormat or URDF furniture instead of "
        "--object (see docs/user_models.md)")
    g.add_argument("--model", default="", metavar="FILE",
                   help="the model file (.sdf or .urdf); needs --joint")
    g.add_argument("--joint", default="", metavar="NAME",
                   help="the revolute or prismatic joint to open")
    g.add_argument("--model-pose", default=None, metavar='"x y z roll pitch yaw"',
                   help="pose of the model frame in the world, m and rad (default: the "
                        "lowest point on the floor, the joint's front facing the robot)")
    g.add_argument("--handle", default=None, metavar='"x y z"',
                   help="the handle point in the model frame, m (default: found from the "
                        "moving part's collision geometry)")


def load_model_args(args):
    """The user model the flags name (None without ``--model``), checked: raises
    ``ValueError`` with a one-line message for a missing or unparsable file, an unknown
    joint, a joint that cannot be operated, no handle, or a handle out of the arm's
    reach."""
    if not args.model:
        for flag, v in (("--joint", args.joint), ("--model-pose", args.model_pose),
                        ("--handle", args.handle)):
            if v:
                raise ValueError(f"{flag} needs --model")
        return None
    if not args.joint:
        raise ValueError("--model needs --joint NAME (the joint to open)")
    from mmlearn.diagrams.articulation.operate import check_reach
    from mmlearn.sdf.user_model import load_user_mechanism, user_model_args

    mech = load_user_mechanism(args.model, args.joint,
                               **user_model_args(args.model_pose, args.handle))
    check_reach(mech)
    return mech
