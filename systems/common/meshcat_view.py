"""Meshcat views that explain themselves: a legend panel (a title and rows of a colour swatch
and a text) fixed to the top-left corner of the view, live and in a recording's standalone
HTML, and a camera framing given points (:func:`frame_camera`).

Every Meshcat recording of the apps draws one, naming each drawn thing in the colours of
the drawing together with the learned numbers it shows (``LearnedModelVisualizer``,
``track_fronts``, ``learn_body_schema``, ``imitate``, ``tactile_state``)."""

from __future__ import annotations

import tempfile
from pathlib import Path

from pydrake.geometry import Mesh, Rgba
from pydrake.math import RigidTransform

__all__ = ["LEGEND_PATH", "LEGEND_KINDS", "draw_legend", "frame_camera"]

#: Meshcat path of the legend: a child of the default camera, so it stays in the top-left
#: corner of the view however the user orbits or zooms (Meshcat adds the objects under a
#: path to the three.js object of its parent; the camera is /Cameras/default/rotated/<object>).
LEGEND_PATH = "/Cameras/default/rotated/<object>/legend"

#: the swatches a row may have: a thick line, a thin line, a dot, a filled box (a body or a
#: translucent ellipsoid) and scattered small dots (a point cloud); "" for a row of text only
LEGEND_KINDS = ("line", "thin", "dot", "box", "dots", "")

# the legend image: pixels per row, least width; its size in the camera frame (three.js: x
# right, y up, looking along -z): drawn _LEGEND_DEPTH in front of the camera, the rows
# _LEGEND_ROW high, the top-left corner at (_LEGEND_LEFT, _LEGEND_TOP). Meshcat's default
# camera has a 75 deg vertical field of view: at 0.1 m the view is +-0.077 m high and, in
# a 4:3 or wider window, at least +-0.102 m wide; the left edge at -0.078 keeps clear of
# the real-time-rate panel (80 px) of Drake's live page in windows from 800 px wide.
_ROW_PX, _MIN_WIDTH_PX, _MAX_WIDTH_PX = 40, 620, 1300
_LEGEND_DEPTH, _LEGEND_ROW = 0.1, 0.0052
_LEGEND_LEFT, _LEGEND_TOP = -0.078, 0.0735


def _font(size: int, bold: bool = False):
    """DejaVu Sans from matplotlib's data (a dependency), else Pillow's own font."""
    from PIL import ImageFont

    try:
        import matplotlib

        name = "DejaVuSans-Bold.ttf" if bold else "DejaVuSans.ttf"
        ttf = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / name
        return ImageFont.truetype(str(ttf), size)
    except (ImportError, OSError):
        return ImageFont.load_default(size=size)


def _swatch_rgb(c: Rgba) -> tuple[int, int, int]:
    # a translucent colour as it looks over the grey floor
    return tuple(int(round(255 * (c.a() * v + 0.6 * (1 - c.a())))) for v in (c.r(), c.g(), c.b()))


def _legend_png(path: Path, title: str, rows) -> tuple[int, int]:
    from PIL import Image, ImageDraw  # Pillow comes with matplotlib

    font_title, font = _font(int(0.6 * _ROW_PX), bold=True), _font(int(0.55 * _ROW_PX))
    need = max([font_title.getlength(title) + 24]
               + [font.getlength(text) + 96 for _, _, text in rows])
    W = int(min(max(_MIN_WIDTH_PX, need), _MAX_WIDTH_PX))
    H = _ROW_PX * (len(rows) + 1) + 12
    img = Image.new("RGB", (W, H), (250, 250, 250))
    d = ImageDraw.Draw(img)
    d.rectangle([0, 0, W - 1, H - 1], outline=(90, 90, 90), width=2)
    d.text((12, 6 + _ROW_PX // 2), title, fill=(0, 0, 0), font=font_title, anchor="lm")
    for i, (c, kind, text) in enumerate(rows):
        if kind not in LEGEND_KINDS:
            raise ValueError(f"legend row kind must be one of {LEGEND_KINDS}, got {kind!r}")
        y = 6 + _ROW_PX * (i + 1) + _ROW_PX // 2
        if c is None or not kind:
            d.text((14, y), text, fill=(60, 60, 60), font=font, anchor="lm")
            continue
        rgb = _swatch_rgb(c)
        if kind == "dot":
            d.ellipse([34, y - 8, 50, y + 8], fill=rgb)
        elif kind == "box":
            d.rectangle([22, y - 11, 62, y + 11], fill=rgb, outline=(90, 90, 90))
        elif kind == "dots":
            for k, (dx, dy) in enumerate(((0, -6), (10, 4), (20, -3), (30, 7), (40, -7),
                                          (46, 2), (5, 8), (26, 9), (36, 0), (15, -9))):
                d.ellipse([16 + dx - 2, y + dy - 2, 16 + dx + 2, y + dy + 2], fill=rgb)
        else:
            d.line([(14, y), (70, y)], fill=rgb, width=8 if kind == "line" else 3)
        d.text((84, y), text, fill=(0, 0, 0), font=font, anchor="lm")
    img.save(path)
    return W, H


def draw_legend(meshcat, title: str, rows, *, path: str = LEGEND_PATH) -> None:
    """Draw a legend panel at ``path``: ``title`` and ``rows`` of ``(colour, kind, text)``
    (``colour`` a ``pydrake.geometry.Rgba`` or None, ``kind`` one of ``LEGEND_KINDS``: the
    swatch drawn in that colour; None or "": a row of text only). Under the default
    ``LEGEND_PATH`` it is fixed to the top-left corner of the view, live and in a
    recording's standalone HTML. The panel is a textured quad (an OBJ with an emissive PNG
    texture, so the scene's lights do not dim it); its text is also in the OBJ's comments,
    so it can be found in a recording's HTML. Raises ValueError for an unknown ``kind``."""
    with tempfile.TemporaryDirectory(prefix="mmlearn_legend_") as tmp:
        tmp = Path(tmp)
        W, H = _legend_png(tmp / "legend.png", title, rows)
        h = _LEGEND_ROW * H / _ROW_PX
        w = h * W / H
        (tmp / "legend.mtl").write_text(
            "newmtl legend\nKa 0 0 0\nKd 0 0 0\nKs 0 0 0\nKe 1 1 1\n"
            "map_Ke legend.png\n")
        (tmp / "legend.obj").write_text(
            f"# mmlearn legend: {title}\n"
            + "".join(f"# {text}\n" for _, _, text in rows)
            + "mtllib legend.mtl\n"
            f"v 0 {-h} 0\nv {w} {-h} 0\nv {w} 0 0\nv 0 0 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl legend\n"
            "f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n")
        meshcat.SetObject(path, Mesh(str(tmp / "legend.obj")))
    meshcat.SetTransform(path, RigidTransform([_LEGEND_LEFT, _LEGEND_TOP, -_LEGEND_DEPTH]))


def frame_camera(meshcat, points, *, view_from, fov_deg: float = 75.0,
                 min_aspect: float = 4 / 3, margin: float = 1.1, min_distance: float = 0.3):
    """Point Meshcat's camera so that every one of ``points`` ((n, 3), world, m) is in view
    and their image is centred, looking along ``-view_from`` (a world direction from the
    scene towards the camera, tilted to look down at least a little).

    ``fov_deg`` is the camera's vertical field of view (Meshcat's default camera: 75 deg);
    the view is assumed at least ``min_aspect`` wide (width / height); the points fill at
    most 1 / ``margin`` of it. With the camera's axes fixed (right r, up v, forward f), a
    point p is in view when ``|(p - C).r| <= tx (p - C).f`` and ``|(p - C).v| <= ty (p -
    C).f``: linear in the camera position C, so the closest C that sees every point, with
    the outermost points on opposite edges equally far in, has a closed form. The orbit
    target is on the view axis at the points' mean depth; the camera stays at least
    ``min_distance`` (m) in front of the nearest point. Sets the live view and, through
    Meshcat's scene, every later ``StaticHtml``. Returns ``(camera position, target)``."""
    import numpy as np

    P = np.asarray(points, float).reshape(-1, 3)
    u = np.asarray(view_from, float)
    u = u / np.linalg.norm(u)
    if u[2] < 0.2:  # look down on the scene, never along or up from the floor
        u[2] = 0.2
        u = u / np.linalg.norm(u)
    f = -u
    right = np.cross(f, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    ty = np.tan(np.radians(fov_deg) / 2) / margin
    tx = ty * min_aspect
    a, b, c = P @ right, P @ f, P @ up
    R, L = np.max(a - tx * b), np.max(-a - tx * b)
    U, D = np.max(c - ty * b), np.max(-c - ty * b)
    c_f = min(-(R + L) / (2 * tx), -(U + D) / (2 * ty), float(b.min()) - float(min_distance))
    camera = (R - L) / 2 * right + (U - D) / 2 * up + c_f * f
    target = camera + f * max(float(np.mean(b)) - c_f, 0.3)
    meshcat.SetCameraPose(camera, target)
    return camera, target
