"""Progress bars (models/common/progress.py) and the opening trial's shared flags
(apps/common/operate_args.py)."""

import argparse

import pytest

from mmlearn.apps.common.operate_args import add_trial_args
from mmlearn.models.common.progress import progress, progress_bar


def test_progress_passes_the_items_through_and_a_disabled_bar_accepts_its_calls():
    assert list(progress(range(5), desc="x")) == [0, 1, 2, 3, 4]
    items = [3, 1, 2]
    assert progress(items, enabled=False) is items
    bar = progress_bar(4, "x", enabled=False)
    bar.update(2)
    bar.set_postfix_str("half")
    bar.close()
    assert bar.disable  # nothing drawn


def test_trial_args_defaults_and_checks():
    ap = argparse.ArgumentParser()
    add_trial_args(ap)
    a = ap.parse_args([])
    assert a.max_time == 60.0 and a.perception == "click"
    assert a.sigma_pos is None and a.base_noise is None  # the trial's own defaults apply
    a = ap.parse_args(["--base-noise", "0", "--perception", "depth", "--sigma-pos", "0.02"])
    assert a.base_noise == 0.0 and a.perception == "depth" and a.sigma_pos == 0.02
    for bad in (["--max-time", "0"], ["--base-noise", "-1"], ["--perception", "radar"]):
        with pytest.raises(SystemExit):
            ap.parse_args(bad)


def test_line_progress_off_a_terminal_reports_count_and_time_left():
    import io

    from mmlearn.models.common.progress import LineProgress

    now = [0.0]
    out = io.StringIO()
    bar = LineProgress(total=1000, desc="trials", unit="trial", interval=30.0, file=out,
                       clock=lambda: now[0])
    for _ in range(10):  # quiet before the first interval
        now[0] += 1.0
        bar.update(10)
    assert out.getvalue() == ""
    now[0] = 40.0
    bar.update(100)  # 200 of 1000 after 40 s: 160 s left
    assert out.getvalue().strip() == ("trials: 200/1000 trial (20.0%), 0:00:40 elapsed, "
                                      "about 0:02:40 left")
    bar.update(1)
    assert bar.lines == 1  # one line per interval
    items = LineProgress(range(3), desc="x", interval=0.0, file=out)
    assert list(items) == [0, 1, 2] and items.lines == 3 and len(items) == 3
