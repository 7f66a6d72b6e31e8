"""Systems articulated objects: link models, structure, priors, operating doors and drawers (thesis ch. 4)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "jam_monitor": ["DynamicsMonitorConfig", "DynamicsMonitorState", "DynamicsMonitor", "RegressionSamples", "GO", "JAMMED", "LOCKED", "HALT_NAMES", "estimate_dynamics", "speed_modulation"],
    "base_localization": ["BaseLocalization", "BaseLocalizationConfig", "FRAMES"],
    "epc_config": ["EpcTask", "EpcConfig"],
    "epc_controller": ["hook_rotation", "EpcController", "CommandInterpolator"],
    "epc_state": ["EpcState", "EpcInputs", "PHASE_NAMES"],
    "estimator": ["ArticulationEstimator", "ArticulationEstimatorState"],
    "model_visualizer": ["legend_entries", "LearnedModelVisualizer", "draw_link_model"],
    "prior_selector": ["ShiftedLinkModel", "PriorModelSelector"],
}

__all__ = [
    "ArticulationEstimator",
    "ArticulationEstimatorState",
    "BaseLocalization",
    "BaseLocalizationConfig",
    "CommandInterpolator",
    "draw_link_model",
    "DynamicsMonitor",
    "DynamicsMonitorConfig",
    "DynamicsMonitorState",
    "EpcConfig",
    "EpcController",
    "EpcInputs",
    "EpcState",
    "EpcTask",
    "estimate_dynamics",
    "FRAMES",
    "GO",
    "HALT_NAMES",
    "hook_rotation",
    "JAMMED",
    "LearnedModelVisualizer",
    "legend_entries",
    "LOCKED",
    "PHASE_NAMES",
    "PriorModelSelector",
    "RegressionSamples",
    "ShiftedLinkModel",
    "speed_modulation",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
