"""Diagrams imitation learning as a DBN of constraints (thesis ch. 8)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "demonstrations": ["TeacherConfig", "TeacherDiagram", "MakeTeacherDiagram", "default_sensor_config", "observations_to_demonstration", "record_demonstration", "record_demonstrations", "draw_demonstrations", "TeacherIKError"],
    "diagram": ["task_scene", "ImitationConfig", "Imitation", "home_position", "hand_ik", "start_configuration", "object_positions", "MakeImitationDiagram"],
    "teaching": ["teach_interactively", "teaching_trial", "OUTCOMES", "TEACHING_PRIOR"],
    "trials": ["reproduce_task", "reproduction_trial", "reproduction_plan", "record_demos", "PLACEMENT", "PARZEN_H", "PARZEN_H_DEFAULT", "SAMPLE_DT", "RELEASE_S", "MAX_TIME_FACTOR"],
}

__all__ = [
    "default_sensor_config",
    "draw_demonstrations",
    "hand_ik",
    "home_position",
    "Imitation",
    "ImitationConfig",
    "MakeImitationDiagram",
    "MakeTeacherDiagram",
    "MAX_TIME_FACTOR",
    "object_positions",
    "observations_to_demonstration",
    "OUTCOMES",
    "PARZEN_H",
    "PARZEN_H_DEFAULT",
    "PLACEMENT",
    "record_demonstration",
    "record_demonstrations",
    "record_demos",
    "RELEASE_S",
    "reproduce_task",
    "reproduction_plan",
    "reproduction_trial",
    "SAMPLE_DT",
    "start_configuration",
    "task_scene",
    "teach_interactively",
    "TeacherConfig",
    "TeacherDiagram",
    "TeacherIKError",
    "TEACHING_PRIOR",
    "teaching_trial",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
