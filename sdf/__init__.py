"""SDFormat models shipped with mmlearn (package data), and their builders.

Use :func:`add_package` to make ``package://mmlearn/<file>`` resolvable by a Drake
``Parser``, or :func:`model_path` for a file's absolute path.
"""

from __future__ import annotations

from pathlib import Path

SDF_DIR = Path(__file__).resolve().parent
PACKAGE_XML = SDF_DIR / "package.xml"


def model_path(name: str) -> Path:
    """Absolute path of a shipped model file (e.g. ``"cabinet.sdf"``)."""
    p = SDF_DIR / name
    if not p.is_file():
        known = sorted(q.name for q in SDF_DIR.glob("*.sdf"))
        raise FileNotFoundError(f"no model {name!r} in {SDF_DIR}; shipped models: {known}")
    return p


def add_package(parser) -> None:
    """Register this folder as the ``mmlearn`` package with a Drake ``Parser``."""
    pm = parser.package_map()
    if not pm.Contains("mmlearn"):
        pm.AddPackageXml(str(PACKAGE_XML))
