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
