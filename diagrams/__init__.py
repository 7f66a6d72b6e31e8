"""Builders that wire plant, scene graph and mmlearn systems into Diagrams."""

from .operate import MakeOperateDiagram, Operate, OperateConfig
from .scene import MakeSceneDiagram, Scene, SceneConfig

__all__ = ["MakeOperateDiagram", "MakeSceneDiagram", "Operate", "OperateConfig", "Scene",
           "SceneConfig"]
