"""Drake LeafSystems of mmlearn: one capability each (ports, state, events).

Import the systems from here, e.g. ``from mmlearn.systems import MarkerSensor``.
"""

from .arm_failures import JointBlocker, PlantFailures
from .articulation_estimator import ArticulationEstimator
from .base_localization import BaseLocalization, BaseLocalizationConfig
from .camera_marker_sensor import CameraMarkerSensor, CameraMarkerSensorConfig
from .dbn_reproducer import DbnReproducer, DbnReproducerConfig
from .dbn_visualizer import DbnVisualizer
from .depth_noise import DepthNoise
from .depth_temporal_filter import DepthTemporalFilter
from .epc_controller import EpcConfig, EpcController, EpcTask
from .container_wall import ContainerWallForce
from .finger_hold import FingerPositionHold
from .front_detector import FrontDetector
from .front_pose import TrueFrontPose
from .front_tracker import FrontTracker, FrontTrackerConfig, FrontTrackerState
from .front_visualizer import FrontTrackVisualizer
from .grasp_attachment import GraspAttachment
from .kinematic_body_poses import KinematicBodyPoses
from .marker_sensor import CameraConfig, MarkerSensor, MarkerSensorConfig
from .model_visualizer import LearnedModelVisualizer
from .motor_babbling import MotorBabbling
from .observations import MarkerObservations
from .plant_helpers import GravityCompensation, JointFriction
from .point_cloud_filter import FinitePointCloud
from .prior_selector import PriorModelSelector
from .schema_controller import SchemaController
from .schema_learner import SchemaLearner, SchemaLearnerConfig, SchemaLearnerState
from .schema_visualizer import SchemaVisualizer
from .tactile_grasp_controller import TactileGraspController
from .tactile_sensor import PadSpec, TactileSensor
from .taxel_visualizer import TaxelPadVisualizer
from .wrist_force_sensor import WristForceSensor

__all__ = [
    "ContainerWallForce",
    "FingerPositionHold",
    "PadSpec",
    "TactileGraspController",
    "TactileSensor",
    "TaxelPadVisualizer",
    "ArticulationEstimator",
    "BaseLocalization",
    "BaseLocalizationConfig",
    "CameraConfig",
    "CameraMarkerSensor",
    "CameraMarkerSensorConfig",
    "DbnReproducer",
    "DbnReproducerConfig",
    "DbnVisualizer",
    "DepthNoise",
    "DepthTemporalFilter",
    "GraspAttachment",
    "EpcConfig",
    "EpcController",
    "EpcTask",
    "FinitePointCloud",
    "FrontDetector",
    "FrontTracker",
    "FrontTrackerConfig",
    "FrontTrackerState",
    "FrontTrackVisualizer",
    "KinematicBodyPoses",
    "GravityCompensation",
    "JointBlocker",
    "JointFriction",
    "LearnedModelVisualizer",
    "MarkerObservations",
    "MarkerSensor",
    "MarkerSensorConfig",
    "MotorBabbling",
    "PlantFailures",
    "PriorModelSelector",
    "SchemaController",
    "SchemaLearner",
    "SchemaLearnerConfig",
    "SchemaLearnerState",
    "SchemaVisualizer",
    "TrueFrontPose",
    "WristForceSensor",
]
