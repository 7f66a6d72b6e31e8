"""Diagrams body schema learning (thesis ch. 3)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "diagram": ["BodySchemaDiagramConfig", "BodySchemaDiagram", "MakeBodySchemaDiagram", "make_target_filter", "true_structure"],
    "trials": ["LearnBodySchemaConfig", "CAMERA_DEPTHS", "camera_config", "structure_rows", "sample_test_commands", "prediction_error", "observation_noise", "control_error", "babble", "learn_body_schema", "make_body_schema_sim", "positioning_error", "drake_accuracy", "drake_recovery", "drake_control", "BLOCKS", "body_schema_trial"],
}

__all__ = [
    "babble",
    "BLOCKS",
    "body_schema_trial",
    "BodySchemaDiagram",
    "BodySchemaDiagramConfig",
    "camera_config",
    "CAMERA_DEPTHS",
    "control_error",
    "drake_accuracy",
    "drake_control",
    "drake_recovery",
    "learn_body_schema",
    "LearnBodySchemaConfig",
    "make_body_schema_sim",
    "make_target_filter",
    "MakeBodySchemaDiagram",
    "observation_noise",
    "positioning_error",
    "prediction_error",
    "sample_test_commands",
    "structure_rows",
    "true_structure",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
