"""Small imitation tasks shared by the model tests: 2-D point-hand reaches, a 3-link planar
arm and task models with constant constraints."""

import numpy as np

from mmlearn.models.imitation.types import Demonstration, TaskModel


def min_jerk(s):
    s = np.clip(s, 0.0, 1.0)
    return 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5


def reach_demos(n=4, seed=0):
    """2-D point-hand reaches from (0, 0) to the target (1, 0): 4 s minimum jerk, 2 s hold."""
    rng = np.random.default_rng(seed)
    demos = []
    for _ in range(n):
        T = 4.0 * rng.uniform(0.9, 1.1)
        t = np.arange(0.0, T + 2.0, 0.2)
        hand = np.outer(min_jerk(t / T), [1.0, 0.0]) + rng.normal(0, 0.005, (len(t), 2))
        demos.append(Demonstration(t=t, hand=hand, objects={"target": np.tile([1.0, 0.0], (len(t), 1))}))
    return demos


# 3-link planar arm (D = 2, n = 3): more joints than Cartesian dimensions
LINKS = np.array([0.4, 0.3, 0.2])


def planar_fk(q):
    c = np.cumsum(q)
    return np.array([np.sum(LINKS * np.cos(c)), np.sum(LINKS * np.sin(c))])


def planar_jacobian(q):
    c = np.cumsum(q)
    J = np.zeros((2, 3))
    for j in range(3):
        J[0, j] = -np.sum(LINKS[j:] * np.sin(c[j:]))
        J[1, j] = np.sum(LINKS[j:] * np.cos(c[j:]))
    return J


def const_model(S, means, variances, D=2):
    names = list(means)
    return TaskModel(t=np.arange(S) * 0.2, constraints=names,
                     mean={c: np.tile(np.asarray(means[c], float), (S, 1)) for c in names},
                     var={c: np.tile(np.asarray(variances[c], float), (S, 1)) for c in names},
                     meta={"D": D, "dt": 0.2})
