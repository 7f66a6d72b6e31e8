"""Systems tactile object recognition and state estimation (thesis ch. 6-7)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "container_wall": ["ContainerWallForce"],
    "finger_hold": ["FingerPositionHold"],
    "grasp_controller": ["TactileGraspController", "GRASP_MODES"],
    "sensor": ["PadSpec", "TactileSensor", "surface_triangles"],
    "taxel_visualizer": ["TaxelPadVisualizer", "taxel_colors"],
}

__all__ = [
    "ContainerWallForce",
    "FingerPositionHold",
    "GRASP_MODES",
    "PadSpec",
    "surface_triangles",
    "TactileGraspController",
    "TactileSensor",
    "taxel_colors",
    "TaxelPadVisualizer",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
