"""Diagrams articulated objects: link models, structure, priors, operating doors and drawers (thesis ch. 4)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "operate": ["OperateConfig", "Operate", "make_task", "task_from_look", "MakeOperateDiagram",
                "HANDLE_HEIGHTS", "check_reach", "WRIST_PERIOD", "WRIST_NOISE_SAMPLES",
                "REFIT_FRACTION"],
    "mechanism_dynamics": ["LATCH_PLAY", "apply_mechanism_options", "dynamics_record", "save_learned_model", "MODEL_SUFFIXES"],
    "operate_perception": ["LookConfig", "LookResult", "LookAtFront", "NoFrontDetected", "front_centre"],
    "trials": ["open_mechanism", "operate_trial", "scene_points", "draw_look", "SENSORS", "observe", "exp_cabinet", "exp_table", "exp_car", "exp_garage", "yardstick_row", "dof_progress", "search_vs_n_row", "STRUCTURE_RUNNERS", "structure_trial"],
}

__all__ = [
    "check_reach",
    "apply_mechanism_options",
    "dof_progress",
    "draw_look",
    "dynamics_record",
    "exp_cabinet",
    "exp_car",
    "exp_garage",
    "exp_table",
    "front_centre",
    "HANDLE_HEIGHTS",
    "LATCH_PLAY",
    "LookAtFront",
    "LookConfig",
    "LookResult",
    "make_task",
    "MakeOperateDiagram",
    "MODEL_SUFFIXES",
    "NoFrontDetected",
    "observe",
    "open_mechanism",
    "Operate",
    "operate_trial",
    "OperateConfig",
    "REFIT_FRACTION",
    "save_learned_model",
    "scene_points",
    "search_vs_n_row",
    "SENSORS",
    "STRUCTURE_RUNNERS",
    "structure_trial",
    "task_from_look",
    "WRIST_NOISE_SAMPLES",
    "WRIST_PERIOD",
    "yardstick_row",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
