"""The structure search's hyper-parameter cache (SearchConfig.warm_start) and the local models'
kernel option (SearchConfig.kernel)."""

import copy
import json

import numpy as np
import pytest

from mmlearn.models.body_schema.schema import SearchConfig
from mmlearn.models.body_schema.evaluation import structure_correct
from mmlearn.models.body_schema.local import LocalModel
from mmlearn.models.body_schema.search import learn_structure
from mmlearn.models.body_schema.kinematic_sim import make_arm_7dof


def _searches(cfg, A, Y, sizes):
    """Searches on growing prefixes of the data, each warm-started from the previous one's
    cache (as the online learner does): (results, fits with optimisation)."""
    cache, out, fits = {}, [], 0
    for n in sizes:
        before = copy.deepcopy(cache)
        res = learn_structure(A[:n], Y[:n], config=cfg, warm_start=cache)
        # the cache passed in is not changed (it may be shared by Drake's state copies)
        assert set(cache) == set(before) and all(
            np.array_equal(cache[k]["search"]["log_ell"], before[k]["search"]["log_ell"])
            for k in before)
        cache = res.hyperparameters
        out.append(res)
        fits += res.n_trained
    return out, fits


@pytest.mark.slow
def test_warm_started_searches_find_the_occluded_structure_with_fewer_fits():
    arm = make_arm_7dof()
    rng = np.random.default_rng(6)
    A = arm.sample_actions(28, rng)
    Y, _ = arm.observe(A, rng, sigma_pos=0.01, sigma_orient=np.deg2rad(1), occluded=[3])
    base = dict(sigma_pos=0.02, sigma_orient=np.deg2rad(3))
    sizes = range(22, 29, 2)
    warm, n_warm = _searches(SearchConfig(**base), A, Y, sizes)
    cold, n_cold = _searches(SearchConfig(**base, warm_start=False), A, Y, sizes)
    for res in warm + cold:
        assert res.complete and structure_correct(arm, res.tree, res.nodes)
        assert (2, 4, (1, 2)) in res.edges()
    assert all(("search" in v and "valid" in v) for v in warm[-1].hyperparameters.values())
    assert n_warm < n_cold


def test_kernel_option_roundtrip_and_validation():
    m = LocalModel(0, 1, (0,), 2, kernel="se+revolute")
    rng = np.random.default_rng(0)
    q = rng.uniform(-1, 1, size=(12, 2))
    Z = np.tile(np.eye(4), (12, 1, 1))
    Z[:, 0, 3] = np.cos(q[:, 0]) + 0.001 * rng.standard_normal(12)
    m.fit(q, Z)
    assert m.gp.revolute and m.gp.log_sb2 is not None
    m2 = LocalModel.from_dict(json.loads(json.dumps(m.to_dict())))
    assert m2.kernel == "se+revolute"
    np.testing.assert_allclose(m2.predict(q), m.predict(q))
    with pytest.raises(ValueError, match="kernel"):
        LocalModel(0, 1, (0,), 2, kernel="periodic")
    with pytest.raises(ValueError, match="kernel"):
        SearchConfig(kernel="rbf")
    with pytest.raises(ValueError, match="refit_growth"):
        SearchConfig(refit_growth=0.5)
