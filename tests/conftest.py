"""Test settings shared by every test module.

Drake must never reach the network here: ``meshcat`` keeps Meshcat local, and
``package_map`` is allowed only because Drake's Parser refuses to start without it when a
remote package (drake_models) is declared; mmlearn never asks for one (see test_sdf.py).
"""

import os
import sys

os.environ["DRAKE_ALLOW_NETWORK"] = "meshcat:package_map"
os.environ.setdefault("MPLBACKEND", "Agg")

PYTHON = sys.executable
