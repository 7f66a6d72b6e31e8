"""Object recognition from tactile images with a bag of tactile features (thesis ch. 6).

A grasp observation is ``z = (Z_left, Z_right, h, w)``: two pad images in [0, 1] (rows along
the finger), the grasp height h (m) and the finger distance w (m)
(:class:`~mmlearn.models.tactile.types.TactileObservation`; a set of them is a
:class:`TactileSet` of stacked arrays). The pipeline:

1. **Distances** (Eq. 6.1-6.3): ``d1`` the L1 distance of two images; ``d2`` its minimum over
   vertical shifts ``tau = -m..m`` of the second image (rows shifted out are dropped, rows
   shifted in are 0 = no pressure); ``dist = alpha (d2_left + d2_right) / s_tac + (1 - alpha)
   |w1 - w2| / s_w`` where ``s_tac`` and ``s_w`` are the standard deviations of the two terms
   over all training pairs ("normalised to unit variance on the training set"). ``d2`` is not
   exactly symmetric (different rows fall off the edge); the clustering uses the symmetrised
   matrix ``(D + D^T) / 2``.
2. **Vocabulary** (6.1.1): ``k`` centres chosen among the training observations by a
   clustering that accepts this distance. The thesis ran k-means; a mean of tactile images is
   not a point of this (non-Euclidean, shift-invariant) space, so the centres here are medoids:
   ``"kmedoids"`` (FasterPAM from the ``kmedoids`` package, GPL-3, optional: ``pip install
   kmedoids``), ``"medoids"`` (this module's own k-medoids, :func:`k_medoids`: a greedy
   build of the k medoids that lower the total distance most, then alternating assignment and
   medoid updates; numpy only) or ``"agglomerative"`` (scikit-learn's average-linkage
   clustering on the precomputed matrix, then the medoid of each cluster). ``"auto"`` uses
   kmedoids when it imports, else ``"medoids"``: average linkage spends medoids on outlying
   single grasps (40 simulated grasps per class: 83.8 % against 88.0 % with kmedoids).
   benchmarks/bench_tactile_recognition.py measures them.
3. **Codebook** (Eq. 6.4): ``h_c,i = sum over the training z of class c of exp(-dist(mu_i, z) /
   l)``, normalised to sum 1 (``l``: length scale in the normalised distance; default
   :data:`LENGTH_SCALE_FRACTION` = 0.2 times the median distance of the training observations
   to their nearest centre).
4. **Likelihood** (Eq. 6.6): the histogram of one observation (same soft assignment,
   normalised) intersected with each class histogram: ``p(z | c) ~ sum_i min(h_z,i, h_c,i)``.
5. **Posterior over several grasps** (Eq. 6.5, 6.8): ``p(c | z_1:t) ~ p(c) prod_j p(z_j | c)``,
   computed in logs.
6. **Next grasp height** (Eq. 6.9-6.13): for each action a (a discretised grasp height), the
   expected information gain ``sum_z p(z | a) I(c; z)`` summed over the training
   observations z taken at a (Eq. 6.12). ``p(z | a)``: with ``weighting="count"`` every
   training observation at a counts ``1 / N_a`` (the thesis' counting estimate); with
   ``"belief"`` (default) each counts in proportion to the current belief in its class,
   ``p(c | z_1:t) / N_a,c``, i.e. the outcomes the robot expects given the grasps so far. The
   outcome likelihoods of the training observations are computed leave-one-out (each against
   its class histogram without itself, :meth:`TactileRecognizer.likelihood_loo`): a training
   observation otherwise finds itself in the codebook and promises more information than a new
   grasp delivers. ``I(c; z) = H(c) - H(c | z)`` (Eq. 6.10) with two estimators of the
   conditional entropy:

   * ``estimator="entropy"``: the entropy of the updated belief, ``H(p(c | z_1:t, z))``, the
     thesis' plug-in. It trusts the likelihood model: a height where the model is *confidently
     wrong* (its posterior collapses onto another class) scores as well as one where it is
     confidently right. On the simulated grasps this happened exactly where training data are
     sparse (the 14-19 cm heights, one grasp per class and height in a training half: single-
     grasp accuracy 0 %, yet the largest expected gains), and the informed heights came out
     worse than random (seed 1: 77.8 vs 83.9 % averaged over t = 1..10).
   * ``estimator="cross_entropy"`` (default): the training outcome's known class c_z gives
     ``H(c | z) ~ -log p(c_z | z_1:t, z)`` (the cross-entropy of the updated belief on the
     labelled outcome), so ``I = log p(c_z | z_1:t, z) - log p(c_z | z_1:t)``: the expected
     rise of the log belief in the true class. Averaged with the belief weights this is
     ``H(c) - CE``, a lower bound of the mutual information I(c; z | z_1:t) (Barber & Agakov
     2003) that is exact when the model's posterior is the true one and penalises outcomes the
     model gets wrong.

   :meth:`TactileRecognizer.next_action` picks the action with the largest gain (6.13) among
   the ``feasible`` ones, preferring those not ``taken`` yet: the naive-Bayes posterior (6.8)
   treats every grasp as independent given the class, but a second grasp of the same object
   at the same height returns nearly the same image (only taxel noise and a 1.5 mm placement
   error differ), so its real information given the first is close to zero while Eq. 6.12
   (computed from independent training outcomes) would promise the full amount again.

Everything is vectorised over observations: the pairwise distances are a handful of
``scipy.spatial.distance.cdist`` calls (one per shift and pad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.distance import cdist

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.tactile.types import TactileDataError, TactileObservation, check_series

__all__ = ["d1", "shift_rows", "d2", "pairwise_d2", "k_medoids", "TactileSet",
           "TactileRecognitionConfig", "TactileRecognizer", "entropy", "posterior", "CLUSTERINGS",
           "kmedoids_available", "height_actions"]

CLUSTERINGS = ("auto", "kmedoids", "medoids", "agglomerative")

LENGTH_SCALE_FRACTION = 0.2
"""Default l of Eq. 6.4 as a fraction of the median distance of the (non-medoid) training
observations to their nearest centre. The thesis gives no value; on the synthetic data of
benchmarks/bench_tactile_recognition.py (seed 1) the T = 10 rate was 0.60 / 0.64 / 0.645 /
0.525 / 0.395 for fractions 0.04 / 0.08 / 0.2 / 0.4 / 0.8: a peaked soft assignment (each
observation's histogram dominated by its nearest few centres) works best."""


# --------------------------------------------------------------------------- distances
def d1(R, S) -> np.ndarray:
    """Eq. 6.1: sum of absolute differences over the last two axes (broadcasts)."""
    return np.abs(np.asarray(R, float) - np.asarray(S, float)).sum(axis=(-2, -1))


def shift_rows(S, tau: int) -> np.ndarray:
    """Shift images ``(..., rows, cols)`` by ``tau`` rows along the finger (positive: towards
    higher row indices); rows shifted in are 0, rows shifted out are dropped."""
    S = np.asarray(S, float)
    out = np.zeros_like(S)
    rows = S.shape[-2]
    if abs(tau) >= rows:
        return out
    if tau > 0:
        out[..., tau:, :] = S[..., :rows - tau, :]
    elif tau < 0:
        out[..., :rows + tau, :] = S[..., -tau:, :]
    else:
        out[...] = S
    return out


def d2(R, S, *, max_shift: int = 2) -> np.ndarray:
    """Eq. 6.2: ``min over tau = -m..m of d1(R, shift(S, tau))`` (broadcasts)."""
    if max_shift < 0:
        raise ValueError(f"max_shift: expected >= 0, got {max_shift}")
    return np.min([d1(R, shift_rows(S, t)) for t in range(-max_shift, max_shift + 1)], axis=0)


def pairwise_d2(A, B, *, max_shift: int = 2) -> np.ndarray:
    """``(nA, nB)`` matrix of ``d2(A[i], B[j])`` for image stacks ``(n, rows, cols)``."""
    A = np.asarray(A, float)
    B = np.asarray(B, float)
    Af = A.reshape(len(A), -1)
    D = None
    for t in range(-max_shift, max_shift + 1):
        Dt = cdist(Af, shift_rows(B, t).reshape(len(B), -1), "cityblock")
        D = Dt if D is None else np.minimum(D, Dt)
    return D


# --------------------------------------------------------------------------- data
@dataclass
class TactileSet:
    """Many ch. 6 observations as stacked arrays.

    Attributes:
        left, right: (N, rows, cols) pad images in [0, 1].
        height: (N,) grasp heights, metres.
        width: (N,) finger distances, metres.
        labels: (N,) class names (object array) or None.
    """

    left: np.ndarray
    right: np.ndarray
    height: np.ndarray
    width: np.ndarray
    labels: np.ndarray | None = None

    def __post_init__(self):
        self.left = check_series("left", self.left, ndim=3, lo=0.0, hi=1.0)
        N = self.left.shape[0]
        if N == 0:
            raise TactileDataError("TactileSet: no observations")
        self.right = check_series("right", self.right, ndim=3, length=N, lo=0.0, hi=1.0)
        if self.right.shape != self.left.shape:
            raise TactileDataError(f"right images {self.right.shape} differ from left "
                                   f"{self.left.shape}")
        self.height = check_series("height", self.height, ndim=1, length=N)
        self.width = check_series("width", self.width, ndim=1, length=N)
        if self.labels is not None:
            self.labels = np.asarray(self.labels, dtype=object)
            if self.labels.shape != (N,):
                raise TactileDataError(f"labels: expected {N}, got shape {self.labels.shape}")

    def __len__(self) -> int:
        return int(self.left.shape[0])

    def subset(self, idx) -> "TactileSet":
        idx = np.asarray(idx)
        return TactileSet(self.left[idx], self.right[idx], self.height[idx], self.width[idx],
                          None if self.labels is None else self.labels[idx])

    @classmethod
    def from_observations(cls, obs) -> "TactileSet":
        obs = list(obs)
        if not obs:
            raise TactileDataError("TactileSet: no observations")
        for o in obs:
            if not isinstance(o, TactileObservation):
                raise TactileDataError(f"expected TactileObservation, got {type(o).__name__}")
        labels = [o.label for o in obs]
        return cls(np.stack([o.left for o in obs]), np.stack([o.right for o in obs]),
                   np.array([o.height for o in obs]), np.array([o.width for o in obs]),
                   None if all(x is None for x in labels) else np.array(labels, dtype=object))


# --------------------------------------------------------------------------- config
@dataclass
class TactileRecognitionConfig:
    """Parameters of the bag-of-features recogniser.

    Attributes:
        k: vocabulary size (number of tactile features; thesis: 50).
        alpha: weight of the tactile term against the width term in Eq. 6.3, in [0, 1]
            (thesis: 0.5).
        max_shift: m of Eq. 6.2, rows (each row of the ch. 6 pad is 51/14 = 3.6 mm).
        length_scale: l of Eq. 6.4 in the normalised distance (unitless); None:
            LENGTH_SCALE_FRACTION times the median distance of the training observations to
            their nearest centre.
        clustering: "auto", "kmedoids" or "agglomerative" (see the module docstring).
        seed: random seed of the clustering.
    """

    k: int = param(50, integer=True, ge=1)
    alpha: float = param(0.5, ge=0, le=1)
    max_shift: int = param(2, unit="rows", integer=True, ge=0)
    length_scale: float | None = param(None, optional=True, gt=0)
    clustering: str = param("auto", choices=CLUSTERINGS)
    seed: int = param(0, integer=True)

    def __post_init__(self):
        validate_fields(self)


def kmedoids_available() -> bool:
    """True when the optional ``kmedoids`` package imports."""
    try:
        import kmedoids  # noqa: F401
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------- probability helpers
def entropy(P, axis: int = -1) -> np.ndarray:
    """Eq. 6.9: ``-sum p log p`` (natural log, 0 log 0 = 0) along ``axis``."""
    P = np.asarray(P, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(P > 0, P * np.log(np.where(P > 0, P, 1.0)), 0.0)
    return -t.sum(axis=axis)


def posterior(log_lik, prior=None) -> np.ndarray:
    """Eq. 6.5 / 6.8: normalised ``prior * prod_j p(z_j | c)`` from log likelihoods ``(t,
    n_classes)`` (or ``(n_classes,)``); ``prior`` defaults to uniform."""
    L = np.atleast_2d(np.asarray(log_lik, float))
    s = L.sum(axis=0)
    if prior is not None:
        pr = np.asarray(prior, float)
        if pr.shape != s.shape or np.any(pr < 0) or not pr.sum() > 0:
            raise ValueError(f"prior: expected {s.shape[0]} non-negative numbers, not all 0")
        with np.errstate(divide="ignore"):
            s = s + np.log(pr)
    s = s - s.max()
    p = np.exp(s)
    return p / p.sum()


def _medoid(D: np.ndarray, idx: np.ndarray) -> int:
    """The member of ``idx`` with the least total distance to the others of ``idx``."""
    return int(idx[np.argmin(D[np.ix_(idx, idx)].sum(axis=1))])


def k_medoids(D: np.ndarray, k: int, *, max_iter: int = 100) -> np.ndarray:
    """k medoids of a precomputed (N, N) distance matrix (symmetric, >= 0): sorted indices.

    Build: start from the observation with the least total distance to all, then add, k - 1
    times, the one that lowers the sum over all observations of the distance to their
    nearest medoid the most (outlying single observations lower it little, so they are not
    chosen before dense groups are covered). Then alternate: assign each observation to its
    nearest medoid, move each medoid to its cluster's observation with the least total
    distance to the cluster, until nothing moves (the total distance never rises).
    Deterministic."""
    D = np.asarray(D, float)
    N = D.shape[0]
    if D.ndim != 2 or D.shape[1] != N or not np.all(np.isfinite(D)):
        raise ValueError(f"k_medoids: D must be a finite square matrix, got {D.shape}")
    if not 1 <= k <= N:
        raise ValueError(f"k_medoids: k must be in [1, {N}], got {k}")
    med = [int(np.argmin(D.sum(axis=1)))]
    near = D[:, med[0]].copy()
    for _ in range(k - 1):
        gain = np.maximum(near[:, None] - D, 0.0).sum(axis=0)  # per candidate column
        gain[med] = -1.0
        j = int(np.argmax(gain))
        med.append(j)
        np.minimum(near, D[:, j], out=near)
    med = np.array(med)
    cost = D[:, med].min(axis=1).sum()
    for _ in range(max_iter):
        lab = np.argmin(D[:, med], axis=1)
        new = med.copy()
        for c in range(k):
            idx = np.flatnonzero(lab == c)
            if len(idx):
                new[c] = _medoid(D, idx)
        new_cost = D[:, new].min(axis=1).sum()
        if new_cost >= cost:  # (also when nothing moved)
            break
        med, cost = new, new_cost
    return np.sort(med)


# --------------------------------------------------------------------------- recogniser
@dataclass
class TactileRecognizer:
    """The learned vocabulary and codebook (fit with :meth:`fit`).

    Attributes:
        (set by :meth:`fit`)
        config: the parameters.
        classes: (n,) class names, the order of every class axis.
        centres: the vocabulary, a TactileSet of the k medoid observations.
        codebook: (n, k) class histograms H (rows sum to 1).
        s_tac: the normalising standard deviation of Eq. 6.3 of the tactile part, L1 units.
        s_w: the normalising standard deviation of Eq. 6.3 of the width, metres.
        length_scale: l used in Eq. 6.4.
        clustering_used: the clustering that ran ("kmedoids", "medoids" or "agglomerative").
    """

    config: TactileRecognitionConfig = field(default_factory=TactileRecognitionConfig)
    classes: np.ndarray | None = None
    centres: TactileSet | None = None
    codebook: np.ndarray | None = None
    s_tac: float = 1.0
    s_w: float = 1.0
    length_scale: float = 1.0
    clustering_used: str = ""
    _raw: np.ndarray | None = field(default=None, repr=False)
    _train_key: tuple | None = field(default=None, repr=False)

    # ---- distances
    def _terms(self, A: TactileSet, B: TactileSet):
        m = self.config.max_shift
        tac = pairwise_d2(A.left, B.left, max_shift=m) + pairwise_d2(A.right, B.right, max_shift=m)
        wd = np.abs(A.width[:, None] - B.width[None, :])
        return tac, wd

    def distance(self, A: TactileSet, B: TactileSet) -> np.ndarray:
        """Eq. 6.3 between every observation of A and of B, ``(len(A), len(B))``, with the
        training set's normalisation."""
        tac, wd = self._terms(A, B)
        a = self.config.alpha
        return a * tac / self.s_tac + (1.0 - a) * wd / self.s_w

    # ---- training
    def fit(self, train: TactileSet) -> "TactileRecognizer":
        """Learn the normalisation, the vocabulary (k centres) and the codebook from labelled
        observations."""
        if train.labels is None:
            raise TactileDataError("fit: the training observations need labels")
        cfg = self.config
        N = len(train)
        if cfg.k > N:
            raise ValueError(f"k: {cfg.k} features need at least {cfg.k} training "
                             f"observations, got {N}")
        tac, wd = self._terms(train, train)
        iu = np.triu_indices(N, 1)
        self.s_tac = float(np.std(tac[iu])) if N > 1 else 1.0
        self.s_w = float(np.std(wd[iu])) if N > 1 else 1.0
        self.s_tac = self.s_tac if self.s_tac > 0 else 1.0
        self.s_w = self.s_w if self.s_w > 0 else 1.0
        a = cfg.alpha
        D = a * tac / self.s_tac + (1.0 - a) * wd / self.s_w
        Ds = 0.5 * (D + D.T)
        medoids, used = self._cluster(Ds, cfg.k, cfg.seed, cfg.clustering)
        self.clustering_used = used
        self.centres = train.subset(medoids)
        Dc = D[medoids].T  # (N, k): dist(mu_i, z) with mu_i first, as Eq. 6.4
        if cfg.length_scale is None:
            near = Dc.min(axis=1)
            near = near[near > 0]
            ls = LENGTH_SCALE_FRACTION * float(np.median(near)) if len(near) else 1.0
            self.length_scale = ls if ls > 0 else 1.0
        else:
            self.length_scale = float(cfg.length_scale)
        self.classes = np.array(sorted(set(train.labels.tolist())), dtype=object)
        Hz = np.exp(-Dc / self.length_scale)
        y = np.searchsorted(self.classes, train.labels)
        H = np.zeros((len(self.classes), cfg.k))
        np.add.at(H, y, Hz)
        self.codebook = H / H.sum(axis=1, keepdims=True)
        self._raw = H
        self._train_key = self._key(train)
        return self

    SCHEMA = "mmlearn.tactile_recognizer/1"

    def to_dict(self) -> dict:
        """A JSON-able record of the fitted model. Schema ``mmlearn.tactile_recognizer/1``:
        ``{"schema", "config": {k, alpha, max_shift, length_scale, clustering, seed},
        "classes": [n names], "centres": {"left", "right": (k, rows, cols) nested lists in
        [0, 1], "height", "width": k numbers (m)}, "codebook": (n, k), "raw_codebook": (n, k)
        unnormalised sums of Eq. 6.4, "s_tac", "s_w" (m), "length_scale", "clustering_used",
        "train_key": fingerprint of the training set (for likelihood_loo)}``."""
        self._check_fitted()
        c = self.config
        return {"schema": self.SCHEMA,
                "config": {"k": int(c.k), "alpha": float(c.alpha), "max_shift": int(c.max_shift),
                           "length_scale": c.length_scale, "clustering": c.clustering,
                           "seed": int(c.seed)},
                "classes": [str(x) for x in self.classes],
                "centres": {"left": self.centres.left.tolist(),
                            "right": self.centres.right.tolist(),
                            "height": self.centres.height.tolist(),
                            "width": self.centres.width.tolist()},
                "codebook": self.codebook.tolist(), "raw_codebook": self._raw.tolist(),
                "s_tac": self.s_tac, "s_w": self.s_w, "length_scale": self.length_scale,
                "clustering_used": self.clustering_used,
                "train_key": list(self._train_key)}

    @classmethod
    def from_dict(cls, d: dict) -> "TactileRecognizer":
        """Inverse of :meth:`to_dict`; ValueError naming the missing or malformed key."""
        if not isinstance(d, dict) or d.get("schema") != cls.SCHEMA:
            raise ValueError(f"tactile recognizer: expected schema {cls.SCHEMA!r}")
        try:
            cfg = TactileRecognitionConfig(**d["config"])
            ce = d["centres"]
            centres = TactileSet(ce["left"], ce["right"], ce["height"], ce["width"])
            rec = cls(cfg, np.array(d["classes"], dtype=object), centres,
                      np.asarray(d["codebook"], float), float(d["s_tac"]), float(d["s_w"]),
                      float(d["length_scale"]), str(d["clustering_used"]))
            rec._raw = np.asarray(d["raw_codebook"], float)
            rec._train_key = tuple(d["train_key"])
        except KeyError as e:
            raise ValueError(f"tactile recognizer: missing key {e}") from None
        except TypeError as e:
            raise ValueError(f"tactile recognizer: {e}") from None
        n, k = len(rec.classes), len(centres)
        for name, a in (("codebook", rec.codebook), ("raw_codebook", rec._raw)):
            if a.shape != (n, k) or not np.all(np.isfinite(a)):
                raise ValueError(f"tactile recognizer: {name} must be finite ({n}, {k}), got "
                                 f"{a.shape}")
        return rec

    @staticmethod
    def _key(ts: TactileSet):
        return (len(ts), float(ts.width.sum()), float(ts.left.sum()), float(ts.height.sum()))

    def likelihood_loo(self, train: TactileSet) -> np.ndarray:
        """Eq. 6.6 for the *training* observations (the set given to :meth:`fit`), each
        against a codebook without its own contribution (leave-one-out): the class histogram
        of z's own class is rebuilt from the other training observations. Without this, a
        training observation always finds itself in its class histogram and looks more
        telling than a new grasp would. (N, n)."""
        self._check_fitted()
        if self._key(train) != self._train_key or train.labels is None:
            raise ValueError("likelihood_loo: pass the labelled set that fit() was given")
        raw = np.exp(-self.distance(self.centres, train).T / self.length_scale)  # (N, k)
        hz = raw / np.maximum(raw.sum(axis=1, keepdims=True), 1e-300)
        L = np.minimum(hz[:, None, :], self.codebook[None, :, :]).sum(axis=2)
        y = np.searchsorted(self.classes, train.labels)
        own = np.maximum(self._raw[y] - raw, 0.0)
        tot = own.sum(axis=1, keepdims=True)
        ok = tot[:, 0] > 0
        own_h = np.where(ok[:, None], own / np.where(tot > 0, tot, 1.0), 0.0)
        L[np.arange(len(y)), y] = np.where(ok, np.minimum(hz, own_h).sum(axis=1), 0.0)
        return L

    @staticmethod
    def _cluster(D: np.ndarray, k: int, seed: int, method: str | None = None):
        method = method or "auto"
        N = D.shape[0]
        if k == N:
            return np.arange(N), "all"
        if method in ("auto", "kmedoids") and kmedoids_available():
            import kmedoids

            res = kmedoids.fasterpam(D, k, random_state=seed, n_cpu=1)
            return np.sort(np.asarray(res.medoids, dtype=int)), "kmedoids"
        if method == "kmedoids":
            raise ImportError("clustering='kmedoids' needs the kmedoids package "
                              "(pip install kmedoids)")
        if method in ("auto", "medoids"):
            return k_medoids(D, k), "medoids"
        from sklearn.cluster import AgglomerativeClustering

        lab = AgglomerativeClustering(n_clusters=k, metric="precomputed",
                                      linkage="average").fit_predict(D)
        med = [_medoid(D, np.flatnonzero(lab == c)) for c in range(k)]
        return np.sort(np.asarray(med, dtype=int)), "agglomerative"

    def _check_fitted(self):
        if self.codebook is None:
            raise RuntimeError("TactileRecognizer: call fit() first")

    # ---- inference
    def histograms(self, obs: TactileSet) -> np.ndarray:
        """Soft feature histograms of single observations (Eq. 6.4 for one z), (N, k)."""
        self._check_fitted()
        Hz = np.exp(-self.distance(self.centres, obs).T / self.length_scale)
        s = Hz.sum(axis=1, keepdims=True)
        return np.where(s > 0, Hz / np.where(s > 0, s, 1.0), 1.0 / Hz.shape[1])

    def likelihood(self, obs: TactileSet) -> np.ndarray:
        """Eq. 6.6: ``sum_i min(h_z,i, h_c,i)`` for every observation and class, (N, n)."""
        hz = self.histograms(obs)
        return np.minimum(hz[:, None, :], self.codebook[None, :, :]).sum(axis=2)

    def posterior(self, obs: TactileSet, prior=None) -> np.ndarray:
        """Eq. 6.8: the class posterior after all observations in ``obs`` (one object)."""
        L = self.likelihood(obs)
        return posterior(np.log(np.maximum(L, 1e-300)), prior)

    def classify(self, obs: TactileSet, prior=None):
        """MAP class (Eq. 6.8) and the posterior after all observations of one object."""
        p = self.posterior(obs, prior)
        return self.classes[int(np.argmax(p))], p

    # ---- active perception
    ESTIMATORS = ("cross_entropy", "entropy")

    def information_gain(self, belief, train: TactileSet, actions, *,
                         train_likelihood=None, weighting: str = "belief",
                         estimator: str = "cross_entropy") -> dict:
        """Eq. 6.12: expected information gain of every action.

        Args:
            belief: (n,) current posterior over ``self.classes`` (p(c | z_1:t)).
            train: the training observations (the outcomes to sum over), labelled.
            actions: (len(train),) action id of every training observation (e.g. its
                discretised height, :func:`height_actions`).
            train_likelihood: optional outcome likelihoods ``(len(train), n)`` (p(z | c) of
                Eq. 6.6, any positive scale per row); default :meth:`likelihood_loo`
                (leave-one-out) when ``train`` is the fitted set, else :meth:`likelihood`.
            weighting: "belief" or "count" (p(z | a), see the module docstring).
            estimator: "cross_entropy" or "entropy" (H(c | z), see the module docstring).

        Returns: {action: expected gain in nats}.
        """
        self._check_fitted()
        n = len(self.classes)
        b = np.asarray(belief, float)
        if b.shape != (n,) or not np.all(np.isfinite(b)) or np.any(b < 0) or not b.sum() > 0:
            raise ValueError(f"belief: expected {n} non-negative numbers, not all 0")
        b = b / b.sum()
        if weighting not in ("belief", "count"):
            raise ValueError(f"weighting: expected 'belief' or 'count', got {weighting!r}")
        if estimator not in self.ESTIMATORS:
            raise ValueError(f"estimator: expected one of {', '.join(self.ESTIMATORS)}, got "
                             f"{estimator!r}")
        acts = np.asarray(actions)
        if acts.shape != (len(train),):
            raise ValueError(f"actions: expected {len(train)} entries, got shape {acts.shape}")
        if train.labels is None:
            raise ValueError("information_gain: the training observations need labels")
        if train_likelihood is not None:
            L = np.asarray(train_likelihood, float)
            if L.shape != (len(train), n) or not np.all(np.isfinite(L)) or np.any(L < 0):
                raise ValueError(f"train_likelihood: expected non-negative finite numbers of "
                                 f"shape {(len(train), n)}, got {L.shape}")
        elif self._key(train) == self._train_key:
            L = self.likelihood_loo(train)
        else:
            L = self.likelihood(train)
        unknown = sorted(set(train.labels.tolist()) - set(self.classes.tolist()))
        if unknown:
            raise ValueError(f"information_gain: training labels {unknown} are not classes "
                             f"of the model")
        y = np.searchsorted(self.classes, train.labels)
        # updated belief p(c | z_1:t, z) for every training outcome z, in logs
        with np.errstate(divide="ignore"):
            lb = np.log(b)
        s = lb[None, :] + np.log(np.maximum(L, 1e-300))
        s = s - s.max(axis=1, keepdims=True)
        logpost = s - np.log(np.exp(s).sum(axis=1, keepdims=True))
        if estimator == "entropy":
            gain = entropy(b) - entropy(np.exp(logpost), axis=1)
        else:
            # log p(c_z | z_1:t, z) - log p(c_z | z_1:t); outcomes of classes the belief has
            # ruled out (b = 0) get weight 0 below
            with np.errstate(invalid="ignore"):
                gain = np.where(b[y] > 0, logpost[np.arange(len(y)), y] - lb[y], 0.0)
        uniq, a_idx = np.unique(acts, return_inverse=True)
        if weighting == "count":
            w = np.ones(len(train))
        else:
            n_ac = np.zeros((len(uniq), n))
            np.add.at(n_ac, (a_idx, y), 1.0)
            w = b[y] / n_ac[a_idx, y]
        tot = np.bincount(a_idx, weights=w, minlength=len(uniq))
        num = np.bincount(a_idx, weights=w * gain, minlength=len(uniq))
        eg = np.where(tot > 0, num / np.where(tot > 0, tot, 1.0), 0.0)
        return {u.item() if hasattr(u, "item") else u: float(g) for u, g in zip(uniq, eg)}

    def next_action(self, belief, train: TactileSet, actions, *, feasible=None, taken=(),
                    **kw):
        """Eq. 6.13: the action with the largest expected information gain, and all gains.

        ``feasible``: the actions that can be executed now (default: every action of the
        training set); ``taken``: actions already executed on this object: the best
        feasible action not yet taken is chosen while there is one (see the module
        docstring), else the best feasible one. Other keywords go to
        :meth:`information_gain`. ValueError when no feasible action has training
        outcomes."""
        g = self.information_gain(belief, train, actions, **kw)
        cand = list(g) if feasible is None else [a for a in g if a in set(feasible)]
        if not cand:
            raise ValueError("next_action: no feasible action has training observations")
        done = set(taken)
        fresh = [a for a in cand if a not in done]
        best = max(fresh or cand, key=lambda a: g[a])
        return best, g


def height_actions(heights, *, resolution: float = 0.005) -> np.ndarray:
    """Discretise grasp heights (m) into action ids: ``round(h / resolution)`` (ints)."""
    h = check_series("heights", heights, ndim=1)
    if not (np.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution: expected a number > 0 (metres), got {resolution!r}")
    return np.round(h / resolution).astype(int)

