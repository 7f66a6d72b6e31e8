"""The global reproduction (models/imitation/global_plan.py, thesis Eq. 8.27-8.28): A* on a
time-expanded roadmap, with a point hand and with a planar arm."""

import numpy as np
import pytest
from imitation_tasks import const_model, planar_fk, planar_jacobian, reach_demos
from mmlearn.models.imitation.dbn import learn_task, reproduce_cartesian
from mmlearn.models.imitation.global_plan import plan_global
from mmlearn.models.imitation.types import ImitationDataError, Obstacle


def test_plan_global_escapes_u_obstacle_where_incremental_is_stuck():
    m = learn_task(reach_demos())
    U = [Obstacle([0.65, 0.0], [0.05, 0.35]), Obstacle([0.45, 0.3], [0.25, 0.05]),
         Obstacle([0.45, -0.3], [0.25, 0.05])]
    objs = {"target": np.array([1.0, 0.0])}

    def clearance(x):
        dense = np.concatenate([np.linspace(a, b, 20) for a, b in zip(x[:-1], x[1:])])
        return min(float(o.signed_distance(dense).min()) for o in U)

    _, inc = reproduce_cartesian(m, [0.0, 0.0], objs, obstacles=U, substeps=5, max_step=0.02)
    assert np.linalg.norm(inc[-1] - [1.0, 0.0]) > 0.3                 # stuck inside the U
    path = plan_global(m, q0=[0.0, 0.0], objects=objs, fk=lambda q: q, jacobian=lambda q: np.eye(2),
                       obstacles=U, seed=1)
    assert path.shape == (m.S, 2) and np.allclose(path[0], 0.0)
    assert np.linalg.norm(path[-1] - [1.0, 0.0]) < 0.02
    assert clearance(path) > 0.0


def test_plan_global_with_arm_kinematics():
    m = const_model(10, {"obj:a": [0.0, 0.0]}, {"obj:a": [1e-4, 1e-4]})
    x_a = np.array([0.3, 0.5])
    path, info = plan_global(m, q0=[0.3, 0.5, 0.4], objects={"a": x_a}, fk=planar_fk, jacobian=planar_jacobian,
                             n_samples=50, return_info=True)
    assert np.linalg.norm(planar_fk(path[-1]) - x_a) < 1e-3 and info["roadmap_nodes"] > 10


def test_plan_global_scipy_and_networkx_agree():
    m = learn_task(reach_demos(n=2, seed=4))
    box = [Obstacle([0.5, 0.0], [0.1, 0.1])]
    kw = dict(q0=[0.0, 0.0], objects={"target": np.array([1.0, 0.0])}, fk=lambda q: q,
              jacobian=lambda q: np.eye(2), obstacles=box, n_samples=80, seed=2, return_info=True)
    p1, i1 = plan_global(m, search="scipy", **kw)
    p2, i2 = plan_global(m, search="networkx", **kw)
    assert i1["graph_edges"] == i2["graph_edges"] > 1000
    assert i1["cost"] == pytest.approx(i2["cost"], rel=1e-9)
    with pytest.raises(ImitationDataError, match="search must be"):
        plan_global(m, search="bfs", **kw)
