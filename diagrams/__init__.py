"""Builders that wire plant, scene graph and mmlearn systems into Diagrams."""

from .scene import MakeSceneDiagram, Scene, SceneConfig

__all__ = ["MakeSceneDiagram", "Scene", "SceneConfig"]
