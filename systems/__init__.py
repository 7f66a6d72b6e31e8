"""Drake LeafSystems of mmlearn: ports, state in the Context, periodic events.

One subpackage per capability, the same names in models, systems and diagrams: ``common``,
``articulation``, ``body_schema``, ``perception``, ``tactile``, ``imitation``. Each lists its
public API in ``__all__``; every one of those names is re-exported here (imported on first
use), e.g. ``from mmlearn.systems import ...``.
"""

from mmlearn._lazy import capability_namespace

CAPABILITIES = ("common", "articulation", "body_schema", "perception", "tactile", "imitation")

#: ``__all__`` (every capability's public names) and ``_EXPORTS`` (capability subpackage ->
#: the public names re-exported from it) are computed on first use; a capability's modules
#: are imported when one of its names is
__getattr__, __dir__ = capability_namespace(__name__, CAPABILITIES)
