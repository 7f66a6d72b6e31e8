"""Compact Gaussian-process regression with independent outputs (thesis Sec. 2.1, Eq. 2.9).

Every output column ``c`` of ``Y`` gets its own zero-mean GP (after subtracting the column mean)
with a squared-exponential kernel plus observation noise::

    k_c(x, x') = sf2_c * exp(-0.5 * sum_d ((x_d - x'_d) / ell_cd)^2) + sn2_c * [x == x']

The hyper-parameters ``theta_c = (log ell_c1..ell_cd, log sf2_c, log sn2_c)`` are fitted by
maximising the log marginal likelihood with analytic gradients (scipy L-BFGS-B). All outputs are
optimised jointly in one vectorised problem: the objective is the sum of the independent
per-output objectives, so its optimum is the per-output optimum.
Its *local* optima are not: one output's line searches can carry another into a different
basin, so ``fit(ell_starts=...)`` adds starts optimised per output.

Optionally (``GaussianProcess(revolute=True)``, a deviation from the thesis' SE kernel for the
body schema's local models, see ``SearchConfig.kernel``) a second term is added::

    k_c(x, x') += sb2_c * prod_d (1 + cos(x_d - x'_d))

Since 1 + cos(a - b) = (1, cos a, sin a) . (1, cos b, sin b), it is Bayesian linear regression
on the products of (1, cos x_d, sin x_d) over the inputs: exactly the functions that the
entries of the relative transform across a chain of revolute joints are (inputs in radians).
It has no length scale; its weight sb2_c is fitted with the others (``log_sb2``, last).

Units: whatever the caller's ``X`` and ``Y`` are in (with ``revolute``, ``X`` in radians);
``ell`` has the units of ``X``, ``sf2``, ``sb2`` and ``sn2`` the units of ``Y`` squared.

Serialisation schema (``to_dict``)::

    {"type": "GaussianProcess", "version": 1, "ard": bool, "noise_min": float or [m floats],
     "X": [[...]] (n, d), "Y": [[...]] (n, m),
     "log_ell": [[...]] (m, d or 1), "log_sf2": [...] (m,), "log_sn2": [...] (m,),
     "revolute": bool (optional, default false), "log_sb2": [...] (m,) (with revolute)}
"""

from __future__ import annotations

import contextlib
import functools
import threading

import numpy as np
from scipy.linalg import lapack
from scipy.optimize import _lbfgsb as _lbfgsb_module
from scipy.optimize import minimize

from mmlearn.models.common.gp_kernel import factorise as _factorise_kernel
from mmlearn.models.common.gp_kernel import neg_lml_and_grad as _nlml_kernel

_potrf = lapack.dpotrf
_potri = lapack.dpotri

__all__ = ["GaussianProcess"]

_LOG_2PI = np.log(2.0 * np.pi)
_NO_P = np.zeros((1, 1))  # the compiled objective's "no revolute term"


_THREADPOOL_CONTROLLER = None
# per thread: how many blas_single_thread() contexts are open (the nested ones are no-ops)
_BLAS_LIMIT = threading.local()


@contextlib.contextmanager
def blas_single_thread():
    """Context manager limiting BLAS to one thread (via threadpoolctl, a scikit-learn
    dependency; a no-op without it). GP matrices here are small: on a shared machine a
    multi-threaded BLAS on 30x30 matrices is several times slower than a single thread.
    Nested uses (a fit inside a structure search inside a schema update) do nothing:
    each threadpoolctl limit costs ~0.1 ms, and a structure search makes hundreds of fits."""
    global _THREADPOOL_CONTROLLER
    depth = getattr(_BLAS_LIMIT, "depth", 0)
    if depth:
        _BLAS_LIMIT.depth = depth + 1
        try:
            yield
        finally:
            _BLAS_LIMIT.depth = depth
        return
    try:
        if _THREADPOOL_CONTROLLER is None:
            from threadpoolctl import ThreadpoolController
            _THREADPOOL_CONTROLLER = ThreadpoolController()
        limit = _THREADPOOL_CONTROLLER.limit(limits=1, user_api="blas")
    except Exception:  # pragma: no cover
        limit = contextlib.nullcontext()
    with limit:
        _BLAS_LIMIT.depth = 1
        try:
            yield
        finally:
            _BLAS_LIMIT.depth = 0


def _as_2d(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise ValueError(f"{name} must be a 2-D array (n, dims), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf")
    return a


@functools.lru_cache(maxsize=64)
def _tri_indices(n: int):
    """Strictly lower-triangle indices of an (n, n) matrix and the mirrored upper ones."""
    lo = np.tril_indices(n, -1)
    return lo, (lo[1], lo[0])


def _inv_l2(log_ell: np.ndarray, m: int, d: int) -> np.ndarray:
    """1 / ell^2 (m, d) from log length scales (m, d), or (m, 1) / (1, d) shared ones."""
    inv = np.exp(-2.0 * np.asarray(log_ell, float))
    return inv if inv.shape == (m, d) else np.broadcast_to(inv, (m, d))


def _minimize_lbfgsb(fun, x0, args, bounds, maxiter: int, ftol: float, gtol: float,
                     maxcor: int = 10, maxls: int = 20):
    """scipy's L-BFGS-B (``minimize(fun, x0, args, jac=True, method="L-BFGS-B", bounds,
    options={maxiter, ftol, gtol})``) on finite ``bounds`` (k, 2), without the per-call
    wrappers of ``minimize``: the same driver loop around scipy's ``setulb`` (the same
    iterates, bit for bit; the tests compare both), which at ~20 evaluations of a 0.1 ms
    objective spends as much time as the objective. Returns an object with ``x``. Falls
    back to ``minimize`` where this scipy's ``setulb`` has another interface."""
    lo = np.ascontiguousarray(bounds[:, 0], dtype=np.float64)
    hi = np.ascontiguousarray(bounds[:, 1], dtype=np.float64)
    setulb = getattr(_lbfgsb_module, "setulb", None)
    if setulb is None or not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        return minimize(fun, x0, args=args, jac=True, method="L-BFGS-B", bounds=bounds,
                        options={"maxiter": maxiter, "ftol": ftol, "gtol": gtol})
    x = np.clip(np.asarray(x0, dtype=np.float64).ravel(), lo, hi)
    n, m = x.size, maxcor
    nbd = np.full(n, 2, np.int32)  # both bounds finite
    f = np.array(0.0, dtype=np.float64)
    g = np.zeros(n, dtype=np.float64)
    wa = np.zeros(2 * m * n + 5 * n + 11 * m * m + 8 * m, np.float64)
    iwa = np.zeros(3 * n, np.int32)
    task = np.zeros(2, np.int32)
    ln_task = np.zeros(2, np.int32)
    lsave = np.zeros(4, np.int32)
    isave = np.zeros(44, np.int32)
    dsave = np.zeros(29, np.float64)
    factr = ftol / np.finfo(float).eps
    iterations = evaluations = 0
    while True:
        g = np.asarray(g, dtype=np.float64)
        try:
            setulb(m, x, lo, hi, nbd, f, g, factr, gtol, wa, iwa, task, lsave, isave, dsave,
                   maxls, ln_task)
        except TypeError:  # another interface: before anything was evaluated
            if evaluations:
                raise
            return minimize(fun, x0, args=args, jac=True, method="L-BFGS-B", bounds=bounds,
                            options={"maxiter": maxiter, "ftol": ftol, "gtol": gtol})
        if task[0] == 3:  # evaluate f and g at x
            f, g = fun(np.copy(x), *args)
            if not (isinstance(g, np.ndarray) and g.ndim == 1):
                g = np.atleast_1d(g)
            evaluations += 1
        elif task[0] == 1:  # a new iterate
            iterations += 1
            if iterations >= maxiter:
                task[0], task[1] = 5, 504
            elif evaluations > 15000:
                task[0], task[1] = 5, 502
        else:
            break
    return _LbfgsResult(x)


class _LbfgsResult:
    def __init__(self, x):
        self.x = x


def _batched_cholesky(K: np.ndarray) -> np.ndarray:
    """Cholesky of a stack (m, n, n); adds growing diagonal jitter if needed."""
    try:
        return np.linalg.cholesky(K)
    except np.linalg.LinAlgError:
        pass
    n = K.shape[-1]
    scale = np.maximum(np.abs(np.diagonal(K, axis1=-2, axis2=-1)).mean(axis=-1), 1e-300)
    eye = np.eye(n)
    for rel in (1e-10, 1e-8, 1e-6, 1e-4, 1e-2):
        try:
            return np.linalg.cholesky(K + (rel * scale)[:, None, None] * eye)
        except np.linalg.LinAlgError:
            continue
    raise np.linalg.LinAlgError("kernel matrix is not positive definite even with jitter")


class GaussianProcess:
    """GP regression, independent outputs, squared-exponential kernel (optionally ARD).

    Args:
        ard: one length scale per input dimension (True) or one shared length scale (False).
        revolute: add the term sb2 * prod_d (1 + cos(x_d - x'_d)) to the kernel (inputs in
            radians; see the module docstring). No effect with 0 inputs.
    """

    def __init__(self, ard: bool = True, revolute: bool = False):
        self.ard = bool(ard)
        self.revolute = bool(revolute)
        self.log_sb2 = None
        self._fitted = False

    # ------------------------------------------------------------------ parameters
    @property
    def n_inputs(self) -> int:
        return self.X.shape[1]

    @property
    def n_outputs(self) -> int:
        return self.Y.shape[1]

    @property
    def length_scales(self) -> np.ndarray:
        """(m, d) length scales (units of X)."""
        ell = np.exp(self.log_ell)
        return np.broadcast_to(ell, (self.Y.shape[1], self.X.shape[1])).copy()

    @property
    def signal_variance(self) -> np.ndarray:
        return np.exp(self.log_sf2)

    @property
    def noise_variance(self) -> np.ndarray:
        return np.exp(self.log_sn2)

    # ------------------------------------------------------------------ core algebra
    def _sqdist(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """(d, a, b) per-dimension squared differences."""
        diff = A.T[:, :, None] - B.T[:, None, :]
        return diff * diff

    def _geom(self, A: np.ndarray, B: np.ndarray):
        """What the kernel needs of two input sets: ((d, a, b) squared differences, the
        (a, b) product prod_d (1 + cos(A_d - B_d)) or None without the revolute term)."""
        D2 = self._sqdist(A, B)
        if not self._has_rev(A.shape[1]):
            return D2, None
        diff = A.T[:, :, None] - B.T[:, None, :]
        return D2, np.prod(1.0 + np.cos(diff), axis=0)

    def _has_rev(self, d: int) -> bool:
        return self.revolute and d > 0

    def _kernel_noiseless(self, D2: np.ndarray, log_ell: np.ndarray, log_sf2: np.ndarray,
                          inv_l2: np.ndarray | None = None):
        """Stack (m, a, b) of sf2 * exp(-0.5 * sum_d D2_d / ell_cd^2) (the SE term);
        ``inv_l2``: 1 / ell^2 (m, d) if the caller has it already."""
        m = log_sf2.shape[0]
        d, a, b = D2.shape
        if d == 0:
            return np.exp(log_sf2)[:, None, None] * np.ones((m, a, b))
        if inv_l2 is None:
            inv_l2 = _inv_l2(log_ell, m, d)
        # one (m, d) x (d, a b) product instead of an einsum: these are small matrices
        r2 = ((-0.5 * inv_l2) @ D2.reshape(d, a * b)).reshape(m, a, b)
        r2 += log_sf2[:, None, None]
        return np.exp(r2, out=r2)

    def _kernel(self, G, log_ell, log_sf2, log_sb2):
        """Full noiseless kernel stack (m, a, b) for geometry ``G`` (see _geom)."""
        D2, P = G
        K = self._kernel_noiseless(D2, log_ell, log_sf2)
        if P is not None:
            K = K + np.exp(log_sb2)[:, None, None] * P
        return K

    def _width(self, d_ell: int, d: int) -> int:
        """Parameters per output: log ell (d_ell), log sf2, log sn2 [, log sb2]."""
        return d_ell + 2 + int(self._has_rev(d))

    def _unpack(self, theta: np.ndarray, m: int, d_ell: int, d: int):
        """(log_ell (m, d_ell), log_sf2 (m,), log_sn2 (m,), log_sb2 (m,) or None)."""
        theta = theta.reshape(m, self._width(d_ell, d))
        sb2 = theta[:, d_ell + 2] if self._has_rev(d) else None
        return theta[:, :d_ell], theta[:, d_ell], theta[:, d_ell + 1], sb2

    def _neg_lml_and_grad(self, theta, G, Yc, d_ell):
        """Negative log marginal likelihood summed over the outputs and its gradient with
        respect to ``theta`` (the objective of L-BFGS-B): the compiled loops of
        models/common/gp_kernel.py; where a kernel matrix is not positive definite, the
        numpy form (:meth:`_neg_lml_and_grad_numpy`, which adds jitter)."""
        D2, P = G
        rev = P is not None
        # (contiguous arrays: one compiled specialisation serves every caller)
        f, g, ok = _nlml_kernel(np.ascontiguousarray(theta, dtype=float),
                                np.ascontiguousarray(D2), np.ascontiguousarray(P) if rev else _NO_P,
                                np.ascontiguousarray(Yc), d_ell,
                                self._width(d_ell, D2.shape[0]), bool(self.ard), rev)
        if ok:
            return f, g
        return self._neg_lml_and_grad_numpy(theta, G, Yc, d_ell)

    def _objective(self, G, Yc, d_ell):
        """theta -> :meth:`_neg_lml_and_grad` (theta, G, Yc, d_ell), with the arrays made
        contiguous once for all the optimiser's evaluations (the same values)."""
        D2, P = G
        rev = P is not None
        D2c, Ycc = np.ascontiguousarray(D2), np.ascontiguousarray(Yc)
        Pc = np.ascontiguousarray(P) if rev else _NO_P
        width, ard = self._width(d_ell, D2.shape[0]), bool(self.ard)

        def fun(theta):
            f, g, ok = _nlml_kernel(np.ascontiguousarray(theta, dtype=float), D2c, Pc, Ycc,
                                    d_ell, width, ard, rev)
            if ok:
                return f, g
            return self._neg_lml_and_grad_numpy(theta, G, Yc, d_ell)

        return fun

    def _neg_lml_and_grad_numpy(self, theta, G, Yc, d_ell):
        """:meth:`_neg_lml_and_grad` in numpy and LAPACK (one Cholesky + inverse per output,
        the rest as products of flattened stacks; jitter where a kernel matrix is not
        positive definite)."""
        D2, P = G
        n, m = Yc.shape
        d = D2.shape[0]
        nn = n * n
        log_ell, log_sf2, log_sn2, log_sb2 = self._unpack(theta, m, d_ell, d)
        inv_l2 = _inv_l2(log_ell, m, d) if d_ell > 0 else None
        Kse = self._kernel_noiseless(D2, log_ell, log_sf2, inv_l2)
        sn2 = np.exp(log_sn2)
        if P is None:
            K = Kse.copy()
        else:
            sb2 = np.exp(log_sb2)
            K = Kse + sb2[:, None, None] * P
        K.reshape(m, nn)[:, ::n + 1] += sn2[:, None]
        Kinv = np.empty_like(K)
        Ldiag = np.empty((m, n))
        for c in range(m):
            Lc, info = _potrf(K[c], lower=1, clean=0)
            if info != 0:
                try:
                    Lc = _batched_cholesky(K[c][None])[0]
                except np.linalg.LinAlgError:
                    return 1e25, np.zeros_like(theta)
            Ldiag[c] = Lc.diagonal()
            Kinv[c], info = _potri(Lc, lower=1)
        logdet_half = np.log(Ldiag).sum(axis=1)
        # potri fills the lower triangle only: mirror it onto the upper one
        lo, up = _tri_indices(n)
        Kinv[:, up[0], up[1]] = Kinv[:, lo[0], lo[1]]
        alpha = np.matmul(Kinv, Yc.T[:, :, None])[:, :, 0]  # (m, n)
        lml = -0.5 * (Yc.T * alpha).sum(axis=1) - logdet_half - 0.5 * n * _LOG_2PI
        W = alpha[:, :, None] * alpha[:, None, :]
        W -= Kinv  # (m, n, n)
        Wf = W.reshape(m, nn)
        WK = Wf * Kse.reshape(m, nn)
        g = np.empty((m, self._width(d_ell, d)))
        if d_ell > 0:
            g_dims = 0.5 * (WK @ D2.reshape(d, nn).T) * inv_l2
            if self.ard:
                g[:, :d_ell] = g_dims
            else:
                g[:, 0] = g_dims.sum(axis=1)
        g[:, d_ell] = 0.5 * WK.sum(axis=1)
        g[:, d_ell + 1] = 0.5 * sn2 * Wf[:, ::n + 1].sum(axis=1)
        if P is not None:
            g[:, d_ell + 2] = 0.5 * sb2 * (Wf @ P.reshape(nn))
        return -float(lml.sum()), -g.ravel()

    def _per_output_nlml(self, theta, G, Yc, d_ell) -> np.ndarray:
        n, m = Yc.shape
        log_ell, log_sf2, log_sn2, log_sb2 = self._unpack(theta, m, d_ell, G[0].shape[0])
        K = self._kernel(G, log_ell, log_sf2, log_sb2) + np.exp(log_sn2)[:, None, None] * np.eye(n)
        try:
            L = _batched_cholesky(K)
        except np.linalg.LinAlgError:
            return np.full(m, np.inf)
        z = np.linalg.solve(L, Yc.T[:, :, None])[:, :, 0]
        return (0.5 * np.einsum("ci,ci->c", z, z)
                + np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1) + 0.5 * n * _LOG_2PI)

    def _factorise(self):
        n, m = self.Y.shape
        Kf = self._kernel(self._geom(self.X, self.X), self.log_ell, self.log_sf2, self.log_sb2)
        K = Kf + np.exp(self.log_sn2)[:, None, None] * np.eye(n)
        # compiled (gp_kernel.factorise); where a K is not positive definite, with jitter
        L, alpha, lml, ok = _factorise_kernel(np.ascontiguousarray(K),
                                              np.ascontiguousarray(self.Y - self.y_mean))
        if ok:
            self._L, self._alpha, self._lml = L, alpha, lml
            self._fitted = True
            return
        self._factorise_numpy(K)

    def _factorise_numpy(self, K):
        """:meth:`_factorise` of the kernel matrices K (m, n, n) in numpy (with growing
        jitter where a K is not positive definite; the tests' reference)."""
        n = K.shape[-1]
        self._L = _batched_cholesky(K)
        Yc = (self.Y - self.y_mean).T[:, :, None]  # (m, n, 1)
        z = np.linalg.solve(self._L, Yc)
        self._alpha = np.linalg.solve(np.swapaxes(self._L, 1, 2), z)[:, :, 0]  # (m, n)
        self._lml = (
            -0.5 * np.einsum("ci,ci->c", z[:, :, 0], z[:, :, 0])
            - np.log(np.diagonal(self._L, axis1=1, axis2=2)).sum(axis=1)
            - 0.5 * n * _LOG_2PI
        )
        self._fitted = True

    # ------------------------------------------------------------------ public API
    def fit(self, X, Y, *, optimize: bool = True, noise_min: float = 1e-6,
            hyperparameters: dict | None = None, maxiter: int = 200,
            n_restarts: int = 0, ftol: float = 1e-9,
            ell_starts=(), extra_starts=()) -> "GaussianProcess":
        """Fit to training inputs ``X`` (n, d) and targets ``Y`` (n, m).

        Args:
            X: (n, d) inputs (d may be 0: the GP then estimates a constant plus noise).
            Y: (n, m) targets; a 1-D array is treated as one output column.
            optimize: maximise the log marginal likelihood over the hyper-parameters.
                If False, the hyper-parameters from ``hyperparameters`` (or the data-scale
                initialisation) are used as they are.
            noise_min: lower bound on the noise *variance* sn2 (units of Y squared): one
                number, or one per output column (m,).
            hyperparameters: optional initial values ``{"log_ell": (m, d) or (m, 1),
                "log_sf2": (m,), "log_sn2": (m,)}`` (broadcast over outputs).
            maxiter: iteration cap for L-BFGS-B.
            ftol: relative tolerance on the objective for L-BFGS-B to stop.
            n_restarts: extra optimiser starts from the data-scale initialisation with a lower
                initial noise (1e-4, 1e-6, ... of the output variance); the best optimum is
                kept per output.
            ell_starts: further starts, optimised *per output* (one L-BFGS-B problem per
                output column, so that one output's line searches cannot carry another into
                a different basin): for each factor f, length scales f x the input std and
                initial noise 1e-2 and 1e-4 of the output variance (or the floor). The
                marginal likelihood of a few dozen noisy samples has a local optimum that
                explains an input's effect as noise (its length scale at the upper bound);
                starts at shorter length scales find the better optimum when there is one.
            extra_starts: further initial values (dicts like ``hyperparameters``), each
                optimised like the first (all outputs jointly); the best optimum is kept per
                output (e.g. warm starts from earlier fits on similar data).
        Returns:
            self
        """
        X = _as_2d(X, "X")
        Y = _as_2d(Y, "Y")
        if X.shape[0] != Y.shape[0]:
            raise ValueError(f"X has {X.shape[0]} rows but Y has {Y.shape[0]}")
        if X.shape[0] < 1:
            raise ValueError("GaussianProcess.fit needs at least one training sample")
        n, d = X.shape
        m = Y.shape[1]
        nm = np.asarray(noise_min, float)
        if nm.ndim > 1 or (nm.ndim == 1 and nm.shape != (m,)):
            raise ValueError(f"noise_min must be a number or one per output ({m},), got shape "
                             f"{nm.shape}")
        if not np.all(nm > 0):
            raise ValueError(f"noise_min must be positive, got {noise_min}")
        self.X, self.Y = X.copy(), Y.copy()
        self.noise_min = float(nm) if nm.ndim == 0 else nm.copy()
        noise_min = np.broadcast_to(nm, (m,))
        self.y_mean = Y.mean(axis=0)
        Yc = Y - self.y_mean
        d_ell = (d if self.ard else 1) if d > 0 else 0

        # data-scale initialisation and bounds
        xs = X.std(axis=0) if n > 1 else np.ones(d)
        xs = np.where(xs > 1e-9, xs, 1.0)
        yvar = Yc.var(axis=0) if n > 1 else np.zeros(m)
        yscale = np.maximum(yvar, 1e-12)
        ell_default = np.log(xs if self.ard or d == 0 else np.array([xs.mean()]))[None, :d_ell]
        ell_default = np.broadcast_to(ell_default, (m, d_ell))
        sf2_default = np.log(np.maximum(yvar, 1e-10))
        rev = self._has_rev(d)
        # the revolute term's diagonal is 2^d: start it at the output variance as well
        sb2_default = sf2_default - d * np.log(2.0)

        def as_theta(h, default_sn2):
            if h is None:
                return self._theta(ell_default, sf2_default, default_sn2,
                                   sb2_default if rev else None)
            log_ell = np.broadcast_to(np.asarray(h["log_ell"], float).reshape(-1, d_ell)
                                      if d_ell else np.zeros((m, 0)), (m, d_ell))
            sb2 = None
            if rev:
                sb2 = (np.broadcast_to(np.asarray(h["log_sb2"], float), (m,))
                       if h.get("log_sb2") is not None else sb2_default)
            return self._theta(log_ell, np.broadcast_to(np.asarray(h["log_sf2"], float), (m,)),
                               np.maximum(np.broadcast_to(np.asarray(h["log_sn2"], float),
                                                          (m,)), np.log(noise_min)), sb2)

        theta0 = as_theta(hyperparameters, np.log(np.maximum(0.01 * yvar, noise_min)))
        extra = [as_theta(h, None) for h in extra_starts]

        with blas_single_thread() if n <= 400 else contextlib.nullcontext():
            theta = self._optimise(X, Y, Yc, theta0, optimize, noise_min, n_restarts, ftol,
                                   maxiter, xs, yvar, yscale, ell_default, sf2_default,
                                   sb2_default, d_ell, tuple(ell_starts), extra)
        self.log_ell, self.log_sf2, self.log_sn2, sb2 = self._unpack(
            np.asarray(theta, float).copy(), m, d_ell, d)
        self.log_sb2 = None if sb2 is None else np.array(sb2)
        with blas_single_thread() if n <= 400 else contextlib.nullcontext():
            self._factorise()
        return self

    def _optimise(self, X, Y, Yc, theta0, optimize, noise_min, n_restarts, ftol, maxiter, xs,
                  yvar, yscale, ell_default, sf2_default, sb2_default, d_ell, ell_starts=(),
                  extra=()):
        n, d = X.shape
        m = Y.shape[1]
        rev = self._has_rev(d)
        if optimize and n > 1:
            if self.ard or d == 0:
                lo_ell, hi_ell = np.log(xs * 1e-2), np.log(xs * 1e5)
            else:
                lo_ell = np.array([np.log(xs.min() * 1e-2)])
                hi_ell = np.array([np.log(xs.max() * 1e5)])
            bounds = []
            for c in range(m):
                bounds += list(zip(lo_ell[:d_ell], hi_ell[:d_ell]))
                bounds.append((np.log(1e-12), np.log(1e4 * yscale[c] + 1e-8)))
                bounds.append((np.log(noise_min[c]),
                               np.log(max(1e4 * yscale[c], 10 * noise_min[c]))))
                if rev:
                    bounds.append((np.log(1e-12), np.log(1e4 * yscale[c] + 1e-8)))
            bounds = np.array(bounds)
            if d == 0:
                return self._constant_optimum(Yc, bounds)
            theta0 = np.clip(theta0.ravel(), bounds[:, 0], bounds[:, 1])
            G = self._geom(X, X)
            starts = [theta0] + [np.clip(t.ravel(), bounds[:, 0], bounds[:, 1]) for t in extra]
            for r in range(int(n_restarts)):
                # further starts with a lower noise level: escapes the "signal is noise"
                # local optimum on (nearly) noise-free data
                t = self._theta(ell_default, sf2_default, np.log(np.maximum(
                    yvar * 10.0 ** (-4 - 2 * r), noise_min)), sb2_default if rev else None)
                starts.append(np.clip(t.ravel(), bounds[:, 0], bounds[:, 1]))
            best, best_f = None, None
            objective = self._objective(G, Yc, d_ell)
            for t0 in starts:
                res = _minimize_lbfgsb(objective, t0, (), bounds, maxiter, ftol, 1e-5)
                if len(starts) == 1 and not (ell_starts and d_ell):
                    return res.x  # nothing to compare per output
                f = self._per_output_nlml(res.x, G, Yc, d_ell)
                if best is None:
                    best, best_f = res.x.reshape(m, -1).copy(), f
                else:  # outputs are independent: keep the better optimum per output
                    better = f < best_f
                    best[better] = res.x.reshape(m, -1)[better]
                    best_f = np.where(better, f, best_f)
            if ell_starts and d_ell:
                self._per_output_starts(best, best_f, G, Yc, d_ell, bounds, ell_starts,
                                        ell_default, sf2_default, sb2_default, yvar, noise_min,
                                        maxiter, ftol)
            return best.ravel()
        return theta0.ravel()

    @staticmethod
    def _constant_optimum(Yc: np.ndarray, bounds: np.ndarray) -> np.ndarray:
        """The exact maximum of the log marginal likelihood within ``bounds`` for 0 inputs
        (every optimiser start ends here, so no L-BFGS-B is run; the body schema's k = 0
        local models are such GPs).

        With no inputs the kernel is K = sf2 11^T + sn2 I. The centred targets y_c are
        orthogonal to 1, so K^-1 y_c = y_c / sn2 and log|K| = (n - 1) log sn2 +
        log(n sf2 + sn2): the likelihood falls with sf2 (its optimum is sf2's lower bound),
        and with a = n sf2 and S = y_c^T y_c, d lml / d sn2 = 0 is the quadratic
        n sn2^2 - (S - (n - 1) a) sn2 - S a = 0 with one positive root; the likelihood is
        unimodal in log sn2, so that root clipped to sn2's bounds is the bounded optimum.
        Returns theta (m * 2,): (log sf2, log sn2) per output."""
        n, m = Yc.shape
        w = bounds.reshape(m, 2, 2)
        log_sf2 = w[:, 0, 0]
        a = n * np.exp(log_sf2)
        S = np.einsum("ic,ic->c", Yc, Yc)
        b = S - (n - 1) * a
        sn2 = (b + np.sqrt(b * b + 4.0 * n * S * a)) / (2.0 * n)
        log_sn2 = np.clip(np.log(np.maximum(sn2, 1e-300)), w[:, 1, 0], w[:, 1, 1])
        return np.stack([log_sf2, log_sn2], axis=1).ravel()

    def _per_output_starts(self, best, best_f, G, Yc, d_ell, bounds, ell_starts, ell_default,
                           sf2_default, sb2_default, yvar, noise_min, maxiter, ftol):
        """Improve ``best`` (m, width) in place with per-output starts (see fit)."""
        m = Yc.shape[1]
        rev = self._has_rev(G[0].shape[0])
        w = best.shape[1]
        for c in range(m):
            bc = bounds[c * w:(c + 1) * w]
            tried = []
            for f in ell_starts:
                for rel in (1e-2, 1e-4):
                    t0 = np.concatenate([ell_default[c] + np.log(f), [sf2_default[c]],
                                         [np.log(max(rel * yvar[c], noise_min[c]))]]
                                        + ([[sb2_default[c]]] if rev else []))
                    t0 = np.clip(t0, bc[:, 0], bc[:, 1])
                    if any(np.allclose(t0, t) for t in tried):
                        continue
                    tried.append(t0)
                    res = minimize(self._neg_lml_and_grad, t0, args=(G, Yc[:, c:c + 1], d_ell),
                                   jac=True, method="L-BFGS-B", bounds=bc,
                                   options={"maxiter": maxiter, "ftol": ftol, "gtol": 1e-5})
                    if np.isfinite(res.fun) and res.fun < best_f[c]:
                        best[c], best_f[c] = res.x, res.fun

    @staticmethod
    def _theta(log_ell, log_sf2, log_sn2, log_sb2=None) -> np.ndarray:
        """(m, width) parameter rows from their parts (log_sb2 last, if any)."""
        cols = [np.asarray(log_ell, float), np.asarray(log_sf2, float)[:, None],
                np.asarray(log_sn2, float)[:, None]]
        if log_sb2 is not None:
            cols.append(np.asarray(log_sb2, float)[:, None])
        return np.concatenate(cols, axis=1)

    def _check_fitted(self):
        if not self._fitted:
            raise ValueError("GaussianProcess is not fitted; call fit() first")

    def _check_xs(self, Xs) -> np.ndarray:
        Xs = np.asarray(Xs, dtype=float)
        if Xs.ndim == 1:
            Xs = Xs[:, None] if self.X.shape[1] == 1 else Xs[None, :]
        if Xs.ndim != 2 or Xs.shape[1] != self.X.shape[1]:
            raise ValueError(f"Xs must have shape (k, {self.X.shape[1]}), got {Xs.shape}")
        if not np.all(np.isfinite(Xs)):
            raise ValueError("Xs contains NaN or inf")
        return Xs

    def predict(self, Xs, return_var: bool = False, *, include_noise: bool = False):
        """Predictive mean (k, m) and optionally variance (k, m) at ``Xs`` (k, d).

        The variance is that of the latent function; ``include_noise=True`` adds the fitted
        noise variance (variance of a new observation).
        """
        self._check_fitted()
        Xs = self._check_xs(Xs)
        Ks = self._kernel(self._geom(Xs, self.X), self.log_ell, self.log_sf2, self.log_sb2)
        # (a batched matrix-vector product; einsum's path search costs more than it at
        # the link models' sizes)
        mean = np.matmul(Ks, self._alpha[:, :, None])[:, :, 0].T + self.y_mean
        if not return_var:
            return mean
        V = np.linalg.solve(self._L, np.swapaxes(Ks, 1, 2))  # (m, n, k)
        prior = np.exp(self.log_sf2)
        if self._has_rev(self.X.shape[1]):
            prior = prior + np.exp(self.log_sb2) * 2.0 ** self.X.shape[1]
        var = prior[None, :] - np.einsum("cnk,cnk->kc", V, V, optimize=True)
        var = np.maximum(var, 0.0)
        if include_noise:
            var = var + np.exp(self.log_sn2)[None, :]
        return mean, var

    def predict_jacobian(self, Xs) -> np.ndarray:
        """Derivative of the predictive mean w.r.t. the inputs: (k, m, d)."""
        self._check_fitted()
        Xs = self._check_xs(Xs)
        m, d = self.Y.shape[1], self.X.shape[1]
        if d == 0:
            return np.zeros((Xs.shape[0], m, 0))
        Ks = self._kernel_noiseless(self._sqdist(Xs, self.X), self.log_ell, self.log_sf2)
        inv_l2 = np.exp(-2.0 * np.broadcast_to(self.log_ell, (m, d)))
        diff = Xs[:, None, :] - self.X[None, :, :]  # (k, n, d)
        KA = Ks * self._alpha[:, None, :]  # (m, k, n)
        J = -np.matmul(KA.transpose(1, 0, 2), diff) * inv_l2[None, :, :]  # (k, m, d)
        if self._has_rev(d):
            # d/dx_e prod_d (1 + cos(x_d - x'_d)) = -sin(x_e - x'_e) prod_{d != e} (...)
            C = 1.0 + np.cos(diff)  # (k, n, d)
            S = -np.sin(diff)
            for e in range(d):
                dP = S[:, :, e] * np.prod(np.delete(C, e, axis=2), axis=2)  # (k, n)
                J[:, :, e] += np.einsum("kn,cn->kc", dP, self._alpha) * np.exp(self.log_sb2)
        return J

    def loo_predict(self):
        """Leave-one-out predictive mean and variance (n, m) at the training inputs: the
        prediction for sample i from the GP conditioned on all other samples (same
        hyper-parameters), in closed form (Rasmussen & Williams, Eq. 5.12). The variance
        includes the noise (it is that of a held-out observation)."""
        self._check_fitted()
        n = self.X.shape[0]
        Linv = np.linalg.solve(self._L, np.broadcast_to(np.eye(n), self._L.shape))
        kinv_diag = np.einsum("cki,cki->ci", Linv, Linv)  # (m, n)
        mean = self.Y - (self._alpha / kinv_diag).T
        return mean, (1.0 / kinv_diag).T

    def hyperparameters(self) -> dict:
        """Current hyper-parameters in log space (a ``hyperparameters=`` argument of fit)."""
        self._check_fitted()
        hp = {"log_ell": self.log_ell.copy(), "log_sf2": self.log_sf2.copy(),
              "log_sn2": self.log_sn2.copy()}
        if self.log_sb2 is not None:
            hp["log_sb2"] = self.log_sb2.copy()
        return hp

    def log_marginal_likelihood(self) -> float:
        """Log marginal likelihood of the training data, summed over outputs."""
        self._check_fitted()
        return float(self._lml.sum())

    def log_marginal_likelihood_per_output(self) -> np.ndarray:
        self._check_fitted()
        return self._lml.copy()

    def to_dict(self) -> dict:
        self._check_fitted()
        return {
            "type": "GaussianProcess", "version": 1, "ard": self.ard,
            "noise_min": np.asarray(self.noise_min).tolist(),
            "X": self.X.tolist(), "Y": self.Y.tolist(),
            "log_ell": self.log_ell.tolist(), "log_sf2": self.log_sf2.tolist(),
            "log_sn2": self.log_sn2.tolist(), "revolute": self.revolute,
            "log_sb2": None if self.log_sb2 is None else self.log_sb2.tolist(),
        }

    @classmethod
    def from_dict(cls, d: dict) -> "GaussianProcess":
        if d.get("type", "GaussianProcess") != "GaussianProcess":
            raise ValueError(f"not a GaussianProcess dict: type={d.get('type')!r}")
        gp = cls(ard=bool(d["ard"]), revolute=bool(d.get("revolute", False)))
        X = np.asarray(d["X"], float)
        Y = np.asarray(d["Y"], float)
        if X.ndim == 1:
            X = X.reshape(len(Y), -1)
        m = Y.shape[1]
        gp.X, gp.Y = X, Y
        nm = np.asarray(d.get("noise_min", 1e-6), float)
        gp.noise_min = float(nm) if nm.ndim == 0 else nm
        gp.y_mean = Y.mean(axis=0)
        gp.log_ell = np.asarray(d["log_ell"], float).reshape(m, -1)
        gp.log_sf2 = np.asarray(d["log_sf2"], float).reshape(m)
        gp.log_sn2 = np.asarray(d["log_sn2"], float).reshape(m)
        if gp._has_rev(X.shape[1]):
            if d.get("log_sb2") is None:
                raise ValueError("GaussianProcess dict: revolute kernel without 'log_sb2'")
            gp.log_sb2 = np.asarray(d["log_sb2"], float).reshape(m)
        gp._factorise()
        return gp
