"""Diagrams body schema learning (thesis ch. 3)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "diagram": ["BodySchemaDiagramConfig", "BodySchemaDiagram", "MakeBodySchemaDiagram", "make_target_filter", "true_structure"],
}

__all__ = [
    "BodySchemaDiagram",
    "BodySchemaDiagramConfig",
    "make_target_filter",
    "MakeBodySchemaDiagram",
    "true_structure",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
