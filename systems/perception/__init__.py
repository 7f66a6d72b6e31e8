"""Systems marker-less perception of cabinet fronts in depth images (thesis ch. 5)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "depth_temporal_filter": ["DepthTemporalFilter"],
    "front_detector": ["FrontDetector", "TIMING_NAMES"],
    "front_pose": ["TrueFrontPose"],
    "front_tracker": ["FrontTracker", "FrontTrackerConfig", "FrontTrackerState"],
    "front_visualizer": ["FrontTrackVisualizer", "track_colour", "front_legend"],
    "point_cloud_filter": ["FinitePointCloud"],
}

__all__ = [
    "DepthTemporalFilter",
    "FinitePointCloud",
    "FrontDetector",
    "FrontTracker",
    "FrontTrackerConfig",
    "FrontTrackerState",
    "FrontTrackVisualizer",
    "front_legend",
    "TIMING_NAMES",
    "track_colour",
    "TrueFrontPose",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
