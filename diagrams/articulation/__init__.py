"""Diagrams articulated objects: link models, structure, priors, operating doors and drawers (thesis ch. 4)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "operate": ["OperateConfig", "Operate", "make_task", "task_from_look", "MakeOperateDiagram"],
    "operate_perception": ["LookConfig", "LookResult", "LookAtFront", "NoFrontDetected", "front_centre"],
    "trials": ["open_mechanism", "operate_trial", "scene_points", "draw_look"],
}

__all__ = [
    "draw_look",
    "front_centre",
    "LookAtFront",
    "LookConfig",
    "LookResult",
    "make_task",
    "MakeOperateDiagram",
    "NoFrontDetected",
    "open_mechanism",
    "Operate",
    "operate_trial",
    "OperateConfig",
    "scene_points",
    "task_from_look",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
