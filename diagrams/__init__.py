"""Builders that wire plant, scene graph and mmlearn systems into Diagrams."""

from .body_schema import BodySchemaDiagram, BodySchemaDiagramConfig, MakeBodySchemaDiagram
from .perception import (FrontPerceptionConfig, FrontPerceptionDiagram,
                         MakeFrontPerceptionDiagram)
from .operate import MakeOperateDiagram, Operate, OperateConfig
from .scene import MakeSceneDiagram, Scene, SceneConfig

__all__ = ["BodySchemaDiagram", "BodySchemaDiagramConfig", "MakeBodySchemaDiagram",
           "FrontPerceptionConfig", "FrontPerceptionDiagram", "MakeFrontPerceptionDiagram",
           "MakeOperateDiagram", "MakeSceneDiagram", "Operate", "OperateConfig", "Scene",
           "SceneConfig"]
