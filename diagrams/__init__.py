"""Builders that wire plant, scene graph and mmlearn systems into Diagrams."""

from .body_schema import BodySchemaDiagram, BodySchemaDiagramConfig, MakeBodySchemaDiagram
from .imitation import Imitation, ImitationConfig, MakeImitationDiagram
from .liquid_roll import LiquidRollConfig, MakeLiquidRollDiagram, simulate_roll
from .operate import MakeOperateDiagram, Operate, OperateConfig
from .perception import (AddFrontDetectorAndTracker, FrontPerceptionConfig,
                         FrontPerceptionDiagram, MakeFrontPerceptionDiagram)
from .scene import MakeSceneDiagram, Scene, SceneConfig
from .tactile_grasp import AddTactileSensor, MakeTactileGraspDiagram, TactileGraspConfig, simulate_grasp

__all__ = ["AddFrontDetectorAndTracker", "AddTactileSensor", "BodySchemaDiagram", "BodySchemaDiagramConfig", "FrontPerceptionConfig",
           "FrontPerceptionDiagram", "MakeBodySchemaDiagram", "MakeFrontPerceptionDiagram",
           "MakeOperateDiagram", "MakeSceneDiagram", "Operate", "OperateConfig", "Scene",
           "SceneConfig", "MakeTactileGraspDiagram", "TactileGraspConfig", "simulate_grasp",
           "Imitation", "ImitationConfig", "MakeImitationDiagram",
           "LiquidRollConfig", "MakeLiquidRollDiagram", "simulate_roll"]
