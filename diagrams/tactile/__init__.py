"""Diagrams tactile object recognition and state estimation (thesis ch. 6-7)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "grasp": ["TactileGraspConfig", "MakeTactileGraspDiagram", "simulate_grasp", "PAD_LAYOUTS", "container_grasp_trial", "grasp_from_record"],
    "liquid_roll": ["LiquidRollConfig", "MakeLiquidRollDiagram", "simulate_roll", "liquid_roll_trial", "LIQUID_CONTAINERS", "dummy_instance", "roll_change_windows"],
    "objects": ["GRIPPER_CH6", "object_grasp_trial", "observation_from_record", "grid_heights"],
}

__all__ = [
    "container_grasp_trial",
    "dummy_instance",
    "grasp_from_record",
    "grid_heights",
    "GRIPPER_CH6",
    "LIQUID_CONTAINERS",
    "liquid_roll_trial",
    "LiquidRollConfig",
    "MakeLiquidRollDiagram",
    "MakeTactileGraspDiagram",
    "object_grasp_trial",
    "observation_from_record",
    "PAD_LAYOUTS",
    "roll_change_windows",
    "simulate_grasp",
    "simulate_roll",
    "TactileGraspConfig",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
