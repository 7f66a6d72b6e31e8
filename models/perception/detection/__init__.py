"""Cabinet fronts as rectangles in dense depth images (thesis ch. 5.1.1-5.1.2), by stage.

:func:`detect_fronts` (:mod:`.pipeline`) runs five stages, the keys of its timings:

- ``planes`` (:mod:`.planes`): sequential RANSAC plane segmentation (Eq. 5.1).
- ``masks`` (:mod:`.labels`, :mod:`.gaps`, :mod:`.rectify`, :mod:`.layers`, :mod:`.grid`):
  one label mask per plane (Eq. 5.2) with the reveals between flush fronts and the offset
  layers, rectified onto a metric grid in the plane.
- ``sampling`` and ``optimisation`` (:mod:`.search`): random starts and greedy side and
  rotation moves on summed-area tables (5.1.2).
- ``check`` (:mod:`.check`, :mod:`.edges`): precision and recall (Eq. 5.4, 5.5), the image
  border, duplicates, sub-cell sides and the plane refit.

The configuration is :class:`FrontDetectorConfig` (:mod:`.config`). What each stage does and
where it departs from the thesis, with the measured reason: ``docs/perception.md``.
"""

from mmlearn.models.perception.detection.config import STAGES, FrontDetectorConfig
from mmlearn.models.perception.detection.pipeline import detect_fronts
from mmlearn.models.perception.detection.planes import Plane

__all__ = ["FrontDetectorConfig", "detect_fronts", "Plane", "STAGES"]
