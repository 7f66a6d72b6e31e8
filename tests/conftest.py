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

# Property-based tests (tests/test_properties.py): one profile for CI and the default run,
# >= 1,000 generated inputs per property, no deadline (the first call imports pydrake),
# derandomized so a failure reproduces. HYPOTHESIS_PROFILE=dev gives 100 random inputs.
try:
    from hypothesis import HealthCheck, settings

    settings.register_profile(
        "ci", max_examples=1000, deadline=None, derandomize=True, database=None,
        print_blob=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                               HealthCheck.filter_too_much])
    settings.register_profile("dev", max_examples=100, deadline=None)
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
except ImportError:  # hypothesis is in the test extra; without it those tests are skipped
    pass
