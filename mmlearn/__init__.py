"""mmlearn: probabilistic model learning for mobile manipulation robots, on Drake.

The subpackages live in the repository's top-level folders and are mapped onto this
namespace by ``pyproject.toml``:

* ``mmlearn.models``   -- the learning and inference (plain numpy/scipy)
* ``mmlearn.systems``  -- Drake LeafSystems wrapping the models
* ``mmlearn.diagrams`` -- builders wiring plant, scene graph and systems
* ``mmlearn.sdf``      -- SDFormat models shipped as package data
* ``mmlearn.apps``     -- runnable programs (``python -m mmlearn.apps.<name>``)
"""

__version__ = "0.1.0"
