"""Models body schema learning (thesis ch. 3)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "evaluation": ["structure_correct", "prediction_errors", "accuracy_curve", "recovery_experiment", "control_experiment", "is_correct", "converged_at", "recovery_summary", "control_summary", "average_runs", "correct_from", "BLOCK_WHERE", "body_schema_report"],
    "kinematic_sim": ["ArmPart", "SimArm", "make_arm_2dof", "make_arm_4dof", "make_arm_7dof", "rot", "trans"],
    "local": ["LocalModel", "EngineeredModel", "se3_inv", "orthonormalize", "pose_errors", "log_likelihood", "relative_poses", "visible_mask", "poses_from_xyzquat"],
    "schema": ["BodySchema", "AdaptationConfig", "SearchConfig", "StructureResult", "learn_structure", "rotation_vector"],
    "search": ["spanning_tree", "check_data"],
}

__all__ = [
    "accuracy_curve",
    "AdaptationConfig",
    "ArmPart",
    "average_runs",
    "BLOCK_WHERE",
    "body_schema_report",
    "BodySchema",
    "check_data",
    "control_experiment",
    "control_summary",
    "converged_at",
    "correct_from",
    "EngineeredModel",
    "is_correct",
    "learn_structure",
    "LocalModel",
    "log_likelihood",
    "make_arm_2dof",
    "make_arm_4dof",
    "make_arm_7dof",
    "orthonormalize",
    "pose_errors",
    "poses_from_xyzquat",
    "prediction_errors",
    "recovery_experiment",
    "recovery_summary",
    "relative_poses",
    "rot",
    "rotation_vector",
    "se3_inv",
    "SearchConfig",
    "SimArm",
    "spanning_tree",
    "structure_correct",
    "StructureResult",
    "trans",
    "visible_mask",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
