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


def run_main(main, argv, capsys):
    """Run an app's ``main(argv)``; returns (exit status, stdout, stderr). argparse errors
    raise SystemExit, the apps' own checks return the status."""
    try:
        rc = main(argv)
    except SystemExit as e:
        rc = e.code
    out, err = capsys.readouterr()
    return rc, out, err


def bad_usage(main, argv, capsys, *needles):
    """``main(argv)`` must exit 2 with a last stderr line holding every needle and no
    traceback; returns that line."""
    rc, out, err = run_main(main, argv, capsys)
    assert rc == 2, (rc, out, err)
    line = err.strip().splitlines()[-1]
    for n in needles:
        assert n in line, (n, err)
    assert "Traceback" not in err
    return line


def perception_frame_at(P, q_target, *, depth_port, t_end, dt=0.02):
    """The first frame of a ``MakeFrontPerceptionDiagram`` ``P`` at which its front's stepped
    opening reaches ``q_target`` (m or rad; stepping time by ``dt`` up to ``t_end`` s):
    (depth image from ``depth_port`` as an (H, W) array, X_WC, the true front pose X_WR, q)."""
    import numpy as np

    ctx = P.diagram.CreateDefaultContext()
    for t in np.arange(0.0, t_end, dt):
        ctx.SetTime(float(t))
        q = float(P.diagram.GetOutputPort("front_joint").Eval(ctx)[0])
        if q >= q_target:
            break
    depth = np.array(P.diagram.GetOutputPort(depth_port).Eval(ctx).data)[..., 0].copy()
    return (depth, P.diagram.GetOutputPort("X_WC").Eval(ctx).GetAsMatrix4(),
            P.diagram.GetOutputPort("X_WR").Eval(ctx).GetAsMatrix4(), q)


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
