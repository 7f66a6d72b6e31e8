"""The learning and inference of mmlearn, plain numpy / scipy (no Drake systems framework).

One subpackage per capability, the same names in models, systems and diagrams: ``common``,
``articulation``, ``body_schema``, ``perception``, ``tactile``, ``imitation``. Each lists its
public API in ``__all__``; every one of those names is re-exported here (imported on first
use), e.g. ``from mmlearn.models import ...``.
"""

from mmlearn._lazy import capability_exports, lazy_exports

CAPABILITIES = ("common", "articulation", "body_schema", "perception", "tactile", "imitation")

#: capability subpackage -> the public names re-exported from it
_EXPORTS = capability_exports(__name__, CAPABILITIES)

__all__ = [name for names in _EXPORTS.values() for name in names]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
