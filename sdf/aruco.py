"""ArUco marker textures for the parts' marker squares (data for the RGB camera).

Every observed part ``<part>`` of an arm or object carries a ``<part>_marker`` frame (+z =
the marker's outward normal, see :mod:`mmlearn.sdf.builders` / :mod:`mmlearn.sdf.objects`).
For a camera that reads real markers, :func:`marker_texture` makes the PNG of one ArUco
marker with a white quiet zone around it and :func:`quad_mesh` a unit square OBJ with
texture coordinates; ``mmlearn.diagrams.common.marker_camera.AddArucoMarkers`` puts the textured
square (scaled to :attr:`ArucoSpec.plate_size`) on every marker frame.

Geometry of one textured plate (in the marker frame, metres)::

    +-------------------------+   plate_size = marker_size + 2 margin
    |  white quiet zone       |
    |   +-----------------+   |
    |   | black border    |   |   marker_size: outer edge of the black border, the size
    |   |  (4x4 data bits)|   |   solvePnP uses
    |   +-----------------+   |
    +-------------------------+

The image's top-left corner is at (-plate/2, +plate/2): the marker frame's x runs to the
right of the printed marker and y upwards, as in OpenCV's ArUco convention, so the pose
``solvePnP`` returns for the detected corners is the ``<part>_marker`` frame itself.

Files are generated on first use (OpenCV's ``generateImageMarker``, no download) into a
cache folder: ``$MMLEARN_CACHE`` if set, else ``~/.cache/mmlearn``, else the system's temp
folder; they are written atomically (temp file + rename), so parallel processes may share it.
"""


import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mmlearn.models.common.config import param, validate_fields

__all__ = ["ArucoSpec", "cache_dir", "marker_texture", "quad_mesh", "dictionary",
           "DICTIONARIES"]

#: ArUco dictionaries that may be named in :attr:`ArucoSpec.dictionary`: name -> (bits per
#: side, number of ids).
DICTIONARIES = {
    "DICT_4X4_50": (4, 50), "DICT_4X4_100": (4, 100), "DICT_4X4_250": (4, 250),
    "DICT_5X5_50": (5, 50), "DICT_5X5_100": (5, 100), "DICT_6X6_50": (6, 50),
}


@dataclass
class ArucoSpec:
    """The printed markers (shared by the textures and the detector).

    Attributes:
        dictionary: OpenCV ArUco dictionary name (see :data:`DICTIONARIES`). 4x4 markers have
            the largest modules for a given size (6 modules across, border included), which
            matters for the small 0.04 m squares of the arms.
        marker_size: outer edge of the black border, m (the models' marker squares are
            0.04 m).
        margin: white quiet zone around the black border on each side, m.
        pixels_per_module: texture resolution, pixels per marker module (bit).
        first_id: ArUco id of the first marker; marker k of a sensor gets first_id + k.
        surface_offset: height of the textured plate above the ``<part>_marker`` frame
            along its normal, m (just above the models' 2-3 mm thick marker squares);
            the sensor subtracts it from the detected pose.
        in_plane_angle_deg: the plate is turned by this angle about the marker frame's
            normal, degrees (the sensor turns the detected pose back). The renderer does
            not anti-alias, so an edge that lies along the pixel grid is only known to
            +-0.5 px; the arms' links are mostly vertical or horizontal in the images, and
            markers turned by 45 degrees keep their edges off the grid (measured: the median
            position error of the 2-DOF arm's markers at ~2 m fell from 17-55 mm to
            see the benchmark).
    """

    dictionary: str = param("DICT_4X4_50", choices=tuple(DICTIONARIES))
    marker_size: float = param(0.04, unit="m", gt=0)
    margin: float = param(0.01, unit="m", ge=0)
    pixels_per_module: int = param(16, unit="px", integer=True, ge=2, le=64)
    first_id: int = param(0, integer=True, ge=0)
    surface_offset: float = param(0.0017, unit="m", ge=0, lt=0.1)
    in_plane_angle_deg: float = param(45.0, unit="deg")

    def validate(self) -> None:
        validate_fields(self)
        if not self.first_id < self.n_ids:
            raise ValueError(f"ArucoSpec: first_id must be an integer in [0, {self.n_ids}) for "
                             f"{self.dictionary}, got {self.first_id!r}")

    @property
    def bits(self) -> int:
        return DICTIONARIES[self.dictionary][0]

    @property
    def n_ids(self) -> int:
        return DICTIONARIES[self.dictionary][1]

    @property
    def plate_size(self) -> float:
        """Edge of the textured square (marker + quiet zone), m."""
        return self.marker_size + 2 * self.margin

    def X_MQ(self):
        """Pose of the textured plate Q in the marker frame M (a ``RigidTransform``)."""
        from pydrake.math import RigidTransform, RotationMatrix

        return RigidTransform(RotationMatrix.MakeZRotation(math.radians(self.in_plane_angle_deg)),
                              [0.0, 0.0, self.surface_offset])

    def ids(self, n: int) -> list[int]:
        """ArUco ids of ``n`` markers; raises ValueError when the dictionary is too small."""
        if self.first_id + n > self.n_ids:
            raise ValueError(f"{n} markers from id {self.first_id} do not fit the "
                             f"{self.n_ids} ids of {self.dictionary}")
        return list(range(self.first_id, self.first_id + n))


def dictionary(name: str):
    """The OpenCV ``cv2.aruco.Dictionary`` called ``name``."""
    import cv2

    if name not in DICTIONARIES:
        raise ValueError(f"unknown ArUco dictionary {name!r}; choose from {sorted(DICTIONARIES)}")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def cache_dir() -> Path:
    """The folder generated textures and meshes go to (created if missing)."""
    env = os.environ.get("MMLEARN_CACHE")
    candidates = ([Path(env)] if env else []) + [Path.home() / ".cache" / "mmlearn",
                                                 Path(tempfile.gettempdir()) / "mmlearn"]
    for c in candidates:
        d = c / "aruco"
        try:
            d.mkdir(parents=True, exist_ok=True)
            if os.access(d, os.W_OK):
                return d
        except OSError:
            continue
    raise OSError(f"no writable cache folder among {[str(c) for c in candidates]}")


def _write_atomic(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def marker_image(spec: ArucoSpec, marker_id: int) -> np.ndarray:
    """The plate texture of ``marker_id`` as a uint8 grey image (black border + bits in the
    middle, white quiet zone); ``marker_size / margin`` is kept to the module grid."""
    import cv2

    spec.validate()
    if not (0 <= int(marker_id) < spec.n_ids):
        raise ValueError(f"marker id {marker_id} is outside [0, {spec.n_ids}) of "
                         f"{spec.dictionary}")
    ppm = spec.pixels_per_module
    modules = spec.bits + 2  # data bits + one-module black border on each side
    side = modules * ppm
    margin_px = int(round(spec.margin / spec.marker_size * side))
    img = cv2.aruco.generateImageMarker(dictionary(spec.dictionary), int(marker_id), side,
                                        borderBits=1)
    out = np.full((side + 2 * margin_px, side + 2 * margin_px), 255, np.uint8)
    out[margin_px:margin_px + side, margin_px:margin_px + side] = img
    return out


def marker_texture(spec: ArucoSpec, marker_id: int) -> Path:
    """Path of the PNG texture of ``marker_id`` (generated on first use)."""
    import cv2

    img = marker_image(spec, marker_id)
    name = (f"{spec.dictionary}_id{int(marker_id)}_ppm{spec.pixels_per_module}"
            f"_m{spec.margin / spec.marker_size:.4f}.png")
    path = cache_dir() / name
    if not path.is_file():
        ok, buf = cv2.imencode(".png", img)
        if not ok:
            raise OSError(f"could not encode the texture of marker {marker_id}")
        _write_atomic(path, buf.tobytes())
    return path


_QUAD = """# unit square in the xy plane, normal +z, texture (0,0) at (-0.5,-0.5)
v -0.5 -0.5 0
v 0.5 -0.5 0
v 0.5 0.5 0
v -0.5 0.5 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
f 1/1/1 2/2/1 3/3/1
f 1/1/1 3/3/1 4/4/1
"""


def quad_mesh() -> Path:
    """Path of a unit square OBJ (xy plane, normal +z, image top-left at (-0.5, +0.5))."""
    path = cache_dir() / "unit_quad.obj"
    if not path.is_file() or path.read_text() != _QUAD:
        _write_atomic(path, _QUAD.encode())
    return path
