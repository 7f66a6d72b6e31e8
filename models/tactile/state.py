"""Internal state of grasped objects from the grasp dynamics (thesis Sec. 7.1-7.2).

From one grasp's finger distance p(t), velocity v(t) = dp/dt and summed force f(t)
(:class:`~mmlearn.models.tactile.types.TactileGrasp`) this module finds the two moments of
Eq. 7.1-7.2 and the six features of Table 7.1 (Eq. 7.3-7.6):

* ``t_first``: the first sample at which both fingers are in contact, i.e. at least
  ``min_fingers`` per-finger forces exceed ``F`` (without per-finger forces: the summed force
  ``f`` exceeds ``F``) -- Eq. 7.1;
* ``t_steady``: the first sample after ``t_first`` at which the gripper is at rest,
  ``|v| < V`` -- Eq. 7.2 (the force-controlled steady state of the switching controller);
* ``a = (p_first, p_steady, f_steady, dt, dp/dt, df/dt)`` -- Eq. 7.7, with ``dp/dt =
  (p_steady - p_first) / dt`` and ``df/dt = (f_steady - f_first) / dt`` (0 when dt = 0).

Special cases (never an exception for a physically possible grasp): a grasp in which the
fingers never both touch anything gives ``contact=False`` and the features of the final state
(``p_first = p_steady = p[-1]``, ``f_steady = f[-1]``, ``dt = 0``, rates 0): the closed hand
on nothing is itself informative (the iCub data set has a "no object" class). A grasp that
never comes to rest gives ``steady=False`` and uses its last sample as ``t_steady``.

Classifiers (Sec. 7.1.2): the thesis used C4.5. scikit-learn's ``DecisionTreeClassifier`` with
``criterion="entropy"`` is CART with information gain (not C4.5's gain ratio, no C4.5
pessimistic pruning; ``min_samples_leaf=2`` is C4.5's default minimum leaf size). A random
forest of such trees is offered for comparison. Evaluation: stratified 10-fold
cross-validation (Sec. 7.1.3: every instance is predicted once by a model not trained on it)
or a train / test split.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mmlearn.models.tactile.types import TactileDataError, TactileGrasp

__all__ = ["FEATURE_NAMES", "GraspFeatures", "extract_grasp_features", "feature_matrix",
           "make_classifier", "ClassificationReport", "cross_validate", "evaluate_split",
           "CLASSIFIERS"]

FEATURE_NAMES = ("p_first", "p_steady", "f_steady", "dt", "dp_dt", "df_dt")
"""Table 7.1, in the order of Eq. 7.7."""

CLASSIFIERS = ("tree", "forest", "boost")


@dataclass
class GraspFeatures:
    """The features of one grasp and how they were found.

    Attributes:
        values: (6,) ``FEATURE_NAMES`` in the grasp's units (p in m, f in N, dt in s, rates
            in m/s and N/s for the gripper).
        i_first, i_steady: sample indices of t_first and t_steady (None without contact).
        contact: both fingers touched the object at some sample.
        steady: the gripper came to rest after contact (else the last sample stands in).
    """

    values: np.ndarray
    i_first: int | None
    i_steady: int | None
    contact: bool
    steady: bool

    def as_dict(self) -> dict:
        return {k: float(v) for k, v in zip(FEATURE_NAMES, self.values)}


def _run_from(mask: np.ndarray, i: int) -> slice:
    """The samples ``i, i+1, ...`` while ``mask`` holds (at least sample ``i``)."""
    rest = mask[i + 1:]
    stop = len(mask) if rest.all() else i + 1 + int(np.argmin(rest))
    return slice(i, stop)


def extract_grasp_features(grasp: TactileGrasp, *, contact_force: float,
                           rest_velocity: float, min_fingers: int = 2,
                           steady_average: bool = False) -> GraspFeatures:
    """Eq. 7.1-7.7 for one grasp.

    Args:
        grasp: the recorded grasp.
        contact_force: threshold F, in the unit of ``grasp.f`` / ``grasp.finger_force``
            (newtons for the simulated gripper); a finger is in contact when its force is > F.
        rest_velocity: threshold V, in the unit of ``grasp.v`` (m/s); at rest when ``|v| < V``.
        min_fingers: how many fingers must be in contact (2 = "both fingers" of a gripper).
        steady_average: take p_steady and f_steady as the means over the steady phase (from
            t_steady while the fingers stay in contact; without contact: the trailing samples
            at rest) instead of the single sample at t_steady (the thesis' reading). Lowers the
            sensor noise in both features; dt and the rates use the same values.
    """
    if not (np.isfinite(contact_force) and contact_force >= 0):
        raise TactileDataError(f"contact_force: expected a finite number >= 0, got {contact_force!r}")
    if not (np.isfinite(rest_velocity) and rest_velocity > 0):
        raise TactileDataError(f"rest_velocity: expected a finite number > 0, got {rest_velocity!r}")
    t, p, v, f = grasp.t, grasp.p, grasp.v, grasp.f
    if grasp.finger_force is not None:
        if grasp.finger_force.shape[1] < min_fingers:
            raise TactileDataError(f"finger_force: {grasp.finger_force.shape[1]} finger(s), "
                                   f"but min_fingers={min_fingers}")
        touching = (grasp.finger_force > contact_force).sum(axis=1) >= min_fingers
    else:
        touching = np.abs(f) > contact_force
    if not touching.any():
        pe, fe = p[-1], f[-1]
        if steady_average:
            still = (np.abs(v) < rest_velocity)[::-1]
            k = max(1, len(still) if still.all() else int(np.argmin(still)))
            pe, fe = p[-k:].mean(), f[-k:].mean()
        vals = np.array([pe, pe, fe, 0.0, 0.0, 0.0])
        return GraspFeatures(vals, None, None, contact=False, steady=False)
    i1 = int(np.argmax(touching))
    rest = np.abs(v) < rest_velocity
    rest[: i1 + 1] = False
    steady = bool(rest.any())
    i2 = int(np.argmax(rest)) if steady else grasp.n - 1
    ps, fs = p[i2], f[i2]
    if steady_average:
        run = _run_from(touching, i2)
        ps, fs = p[run].mean(), f[run].mean()
    dt = float(t[i2] - t[i1])
    dp = (ps - p[i1]) / dt if dt > 0 else 0.0
    df = (fs - f[i1]) / dt if dt > 0 else 0.0
    vals = np.array([p[i1], ps, fs, dt, dp, df], dtype=float)
    return GraspFeatures(vals, i1, i2, contact=True, steady=steady)


def feature_matrix(grasps, **kw) -> tuple[np.ndarray, list[GraspFeatures]]:
    """Features of many grasps: ``(n, 6)`` matrix and the per-grasp records
    (keyword arguments as :func:`extract_grasp_features`)."""
    feats = [extract_grasp_features(g, **kw) for g in grasps]
    X = np.array([ft.values for ft in feats], dtype=float).reshape(len(feats), len(FEATURE_NAMES))
    return X, feats


def make_classifier(kind: str = "tree", *, seed: int = 0, n_trees: int = 300):
    """A scikit-learn classifier: ``"tree"`` (decision tree, entropy criterion, at least 2
    samples per leaf as C4.5's default), ``"forest"`` (random forest of ``n_trees`` such
    trees on bootstrap samples, sqrt(n_features) candidate features per split) or ``"boost"``
    (gradient boosting: 100 depth-3 regression trees on the log-loss, learning rate 0.1,
    scikit-learn's defaults)."""
    from sklearn.ensemble import GradientBoostingClassifier, RandomForestClassifier
    from sklearn.tree import DecisionTreeClassifier

    if kind == "tree":
        return DecisionTreeClassifier(criterion="entropy", min_samples_leaf=2, random_state=seed)
    if kind == "forest":
        return RandomForestClassifier(n_estimators=n_trees, criterion="entropy",
                                      random_state=seed, n_jobs=1)
    if kind == "boost":
        return GradientBoostingClassifier(random_state=seed)
    raise ValueError(f"classifier: unknown {kind!r}; choose from {', '.join(CLASSIFIERS)}")


@dataclass
class ClassificationReport:
    """Predictions against truth.

    Attributes:
        labels: class names in the order of the confusion matrix.
        confusion: (n, n) counts, rows = true class, columns = predicted class.
        y_true, y_pred: per instance.
    """

    labels: list
    confusion: np.ndarray
    y_true: np.ndarray
    y_pred: np.ndarray

    @property
    def rate(self) -> float:
        """Fraction of instances predicted correctly."""
        return float(np.mean(self.y_true == self.y_pred)) if len(self.y_true) else float("nan")

    def per_class(self) -> dict:
        """Class -> fraction of its instances predicted correctly (recall)."""
        out = {}
        for i, c in enumerate(self.labels):
            n = self.confusion[i].sum()
            out[c] = float(self.confusion[i, i] / n) if n else float("nan")
        return out

    def to_dict(self) -> dict:
        return {"rate": self.rate, "n": int(len(self.y_true)), "per_class": self.per_class(),
                "labels": list(self.labels), "confusion": self.confusion.astype(int).tolist()}


def _report(y_true, y_pred, labels=None) -> ClassificationReport:
    from sklearn.metrics import confusion_matrix

    y_true = np.asarray(y_true)
    y_pred = np.asarray(y_pred)
    if labels is None:
        labels = sorted(set(y_true.tolist()) | set(y_pred.tolist()))
    C = confusion_matrix(y_true, y_pred, labels=labels)
    return ClassificationReport(list(labels), C, y_true, y_pred)


def _check_xy(X, y):
    X = np.asarray(X, dtype=float)
    y = np.asarray(y)
    if X.ndim != 2 or X.shape[0] == 0:
        raise ValueError(f"features: expected a non-empty (n, d) matrix, got shape {X.shape}")
    if y.shape != (X.shape[0],):
        raise ValueError(f"labels: expected {X.shape[0]} labels, got shape {y.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError("features: NaN or infinite values")
    return X, y


def cross_validate(X, y, *, classifier: str = "tree", folds: int = 10, seed: int = 0,
                   groups=None) -> ClassificationReport:
    """Stratified ``folds``-fold cross-validation (shuffled with ``seed``): every instance is
    predicted by a classifier trained on the other folds. With ``groups`` (one id per
    instance), instances of one group never straddle training and test (GroupKFold-style,
    stratified)."""
    from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold

    X, y = _check_xy(X, y)
    _, counts = np.unique(y, return_counts=True)
    if folds < 2:
        raise ValueError(f"folds: expected at least 2, got {folds}")
    if counts.min() < folds:
        raise ValueError(f"folds: {folds}-fold cross-validation needs at least {folds} "
                         f"instances per class; the smallest class has {counts.min()}")
    if groups is None:
        splitter = StratifiedKFold(n_splits=folds, shuffle=True, random_state=seed)
        splits = splitter.split(X, y)
    else:
        splitter = StratifiedGroupKFold(n_splits=folds, shuffle=True, random_state=seed)
        splits = splitter.split(X, y, groups)
    y_pred = np.empty(len(y), dtype=y.dtype)
    for train, test in splits:
        clf = make_classifier(classifier, seed=seed)
        clf.fit(X[train], y[train])
        y_pred[test] = clf.predict(X[test])
    return _report(y, y_pred, sorted(set(y.tolist())))


def evaluate_split(X_train, y_train, X_test, y_test, *, classifier: str = "tree",
                   seed: int = 0) -> tuple[ClassificationReport, object]:
    """Train on one set, predict the other; returns (report, fitted classifier)."""
    X_train, y_train = _check_xy(X_train, y_train)
    X_test, y_test = _check_xy(X_test, y_test)
    if X_train.shape[1] != X_test.shape[1]:
        raise ValueError(f"features: training has {X_train.shape[1]} columns, test "
                         f"{X_test.shape[1]}")
    clf = make_classifier(classifier, seed=seed)
    clf.fit(X_train, y_train)
    labels = sorted(set(y_train.tolist()) | set(y_test.tolist()))
    return _report(y_test, clf.predict(X_test), labels), clf
