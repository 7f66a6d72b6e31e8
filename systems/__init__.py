"""Drake LeafSystems of mmlearn: one capability each (ports, state, events).

Import the systems from here, e.g. ``from mmlearn.systems import MarkerSensor``.
"""

from .marker_sensor import CameraConfig, MarkerSensor, MarkerSensorConfig
from .motor_babbling import MotorBabbling
from .observations import MarkerObservations
from .plant_helpers import GravityCompensation, JointFriction

__all__ = [
    "CameraConfig",
    "GravityCompensation",
    "JointFriction",
    "MarkerObservations",
    "MarkerSensor",
    "MarkerSensorConfig",
    "MotorBabbling",
]
