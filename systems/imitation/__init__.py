"""Systems imitation learning as a DBN of constraints (thesis ch. 8)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "dbn_reproducer": ["DbnReproducerConfig", "DbnReproducer"],
    "dbn_visualizer": ["draw_demonstrations", "draw_task_model", "DbnVisualizer"],
    "grasp_attachment": ["GraspAttachment"],
    "kinematic_body_poses": ["KinematicBodyPoses"],
}

__all__ = [
    "DbnReproducer",
    "DbnReproducerConfig",
    "DbnVisualizer",
    "draw_demonstrations",
    "draw_task_model",
    "GraspAttachment",
    "KinematicBodyPoses",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
