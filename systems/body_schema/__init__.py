"""Systems body schema learning (thesis ch. 3)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "arm_failures": ["JointBlocker", "PlantFailures"],
    "controller": ["SchemaController"],
    "learner": ["SchemaLearner", "SchemaLearnerConfig", "SchemaLearnerState", "learn_sample"],
    "motor_babbling": ["MotorBabbling"],
    "visualizer": ["SchemaVisualizer"],
}

__all__ = [
    "JointBlocker",
    "learn_sample",
    "MotorBabbling",
    "PlantFailures",
    "SchemaController",
    "SchemaLearner",
    "SchemaLearnerConfig",
    "SchemaLearnerState",
    "SchemaVisualizer",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
