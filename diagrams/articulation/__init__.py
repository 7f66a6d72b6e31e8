"""Diagrams articulated objects: link models, structure, priors, operating doors and drawers (thesis ch. 4)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "operate": ["OperateConfig", "Operate", "make_task", "task_from_look", "MakeOperateDiagram"],
    "operate_perception": ["LookConfig", "LookResult", "LookAtFront", "NoFrontDetected", "front_centre"],
}

__all__ = [
    "front_centre",
    "LookAtFront",
    "LookConfig",
    "LookResult",
    "make_task",
    "MakeOperateDiagram",
    "NoFrontDetected",
    "Operate",
    "OperateConfig",
    "task_from_look",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
