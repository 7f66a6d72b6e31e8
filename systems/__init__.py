"""Drake LeafSystems of mmlearn: one capability each (ports, state, events).

Import the systems from here, e.g. ``from mmlearn.systems import MarkerSensor``.
"""

from .articulation_estimator import ArticulationEstimator
from .epc_controller import EpcConfig, EpcController, EpcTask
from .marker_sensor import CameraConfig, MarkerSensor, MarkerSensorConfig
from .model_visualizer import LearnedModelVisualizer
from .motor_babbling import MotorBabbling
from .observations import MarkerObservations
from .plant_helpers import GravityCompensation, JointFriction
from .wrist_force_sensor import WristForceSensor

__all__ = [
    "ArticulationEstimator",
    "CameraConfig",
    "EpcConfig",
    "EpcController",
    "EpcTask",
    "LearnedModelVisualizer",
    "WristForceSensor",
    "GravityCompensation",
    "JointFriction",
    "MarkerObservations",
    "MarkerSensor",
    "MarkerSensorConfig",
    "MotorBabbling",
]
