"""Diagrams tactile object recognition and state estimation (thesis ch. 6-7)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "grasp": ["TactileGraspConfig", "MakeTactileGraspDiagram", "simulate_grasp", "simulate_contact_force", "AddTactileSensor", "PAD_LAYOUTS", "PALM_SLIDE_DAMPING"],
    "liquid_roll": ["LiquidRollConfig", "MakeLiquidRollDiagram", "simulate_roll", "LIQUID_CONTAINERS", "LIQUID_VISCOSITY", "dummy_instance", "make_instance", "roll_change_windows", "roll_trajectory"],
    "trials": ["container_grasp_trial", "container_grasp_plan", "SWEEP_FORCES", "odwalla_sweep_plan", "object_grasp_trial", "object_grasp_plan", "GRIPPER_CH6", "grid_heights", "liquid_roll_trial", "liquid_roll_plan"],
}

__all__ = [
    "AddTactileSensor",
    "container_grasp_plan",
    "container_grasp_trial",
    "dummy_instance",
    "grid_heights",
    "GRIPPER_CH6",
    "LIQUID_CONTAINERS",
    "liquid_roll_plan",
    "liquid_roll_trial",
    "LIQUID_VISCOSITY",
    "LiquidRollConfig",
    "make_instance",
    "MakeLiquidRollDiagram",
    "MakeTactileGraspDiagram",
    "object_grasp_plan",
    "object_grasp_trial",
    "odwalla_sweep_plan",
    "PAD_LAYOUTS",
    "PALM_SLIDE_DAMPING",
    "roll_change_windows",
    "roll_trajectory",
    "simulate_contact_force",
    "simulate_grasp",
    "simulate_roll",
    "SWEEP_FORCES",
    "TactileGraspConfig",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
