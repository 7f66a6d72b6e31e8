"""MotorBabbling: random joint targets, smoothly interpolated (thesis ch. 3 "motor babbling")."""

from __future__ import annotations

import math

import numpy as np

from pydrake.systems.framework import BasicVector, LeafSystem


class MotorBabbling(LeafSystem):
    """Outputs commanded joint positions that move between random targets.

    A new target is drawn uniformly inside [lower, upper] every ``period`` seconds; between
    targets the command follows a cosine blend (zero velocity at each target). The targets
    are a pure function of (seed, segment index), so the output is reproducible and
    stateless.

    .. pydrake_system::

        name: MotorBabbling
        output_ports:
        - command

    Args:
        lower, upper: per-action limits (rad or m), same length n >= 1, lower <= upper.
        period: seconds per target (> 0).
        seed: random seed.
        start: command at t = 0 (default: the middle of the range).
        hold: fraction of each period spent resting at the target, in [0, 1).
        accept: optional predicate ``accept(q) -> bool`` (e.g. "reachable and
            collision-free", see :func:`mmlearn.diagrams.body_schema.diagram.make_target_filter`);
            a rejected target is redrawn (the same seed stream) up to ``max_tries`` times,
            after which the last draw is used. None (default) accepts every target.
        max_tries: draws per target when ``accept`` is given (>= 1).
        n_targets: targets drawn in advance (>= 1); with the default period of 1.5 s,
            512 targets last 768 s of babbling.
    """

    def __init__(self, *, lower, upper, period: float = 1.5, seed: int = 0, start=None,
                 hold: float = 0.3, accept=None, max_tries: int = 50,
                 n_targets: int = 512):
        super().__init__()
        lo, hi = np.asarray(lower, float).ravel(), np.asarray(upper, float).ravel()
        if lo.shape != hi.shape or lo.size == 0:
            raise ValueError(f"MotorBabbling: lower {lo.shape} and upper {hi.shape} must be "
                             "non-empty and of equal length")
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))) or np.any(hi < lo):
            raise ValueError("MotorBabbling: limits must be finite with lower <= upper")
        if not period > 0:
            raise ValueError(f"MotorBabbling: period must be > 0, got {period}")
        if not 0 <= hold < 1:
            raise ValueError(f"MotorBabbling: hold must be in [0, 1), got {hold}")
        if accept is not None and not callable(accept):
            raise ValueError("MotorBabbling: accept must be callable or None")
        if int(max_tries) < 1:
            raise ValueError(f"MotorBabbling: max_tries must be >= 1, got {max_tries}")
        if int(n_targets) < 1:
            raise ValueError(f"MotorBabbling: n_targets must be >= 1, got {n_targets}")
        self._accept, self._max_tries = accept, int(max_tries)
        self._lo, self._hi, self._period, self._seed, self._hold = lo, hi, period, seed, hold
        self._start = (0.5 * (lo + hi) if start is None
                       else np.clip(np.asarray(start, float).ravel(), lo, hi))
        if self._start.shape != lo.shape:
            raise ValueError("MotorBabbling: start must have the same length as the limits")
        # targets 1..n_targets, drawn once here (read-only afterwards)
        self._targets = np.array([self._draw(k) for k in range(1, int(n_targets) + 1)])
        self._targets.setflags(write=False)
        self._out = self.DeclareVectorOutputPort("command", BasicVector(lo.size), self._calc,
                                                 prerequisites_of_calc={self.time_ticket()})

    def get_command_output_port(self):
        return self._out

    def _draw(self, k: int) -> np.ndarray:
        rng = np.random.default_rng([self._seed, k])
        q = rng.uniform(self._lo, self._hi)
        if self._accept is not None:
            for _ in range(self._max_tries - 1):
                if self._accept(q):
                    break
                q = rng.uniform(self._lo, self._hi)
        return q

    @property
    def n_targets(self) -> int:
        return len(self._targets)

    def target(self, k: int) -> np.ndarray:
        """The k-th target (k = 0 is the start)."""
        if k <= 0:
            return self._start.copy()
        return self._targets[(k - 1) % len(self._targets)].copy()

    def command(self, t: float) -> np.ndarray:
        k = int(np.floor(t / self._period))
        s = (t - k * self._period) / self._period
        s = min(1.0, s / (1.0 - self._hold))
        w = 0.5 - 0.5 * math.cos(math.pi * s)
        return (1 - w) * self.target(k) + w * self.target(k + 1)

    def _calc(self, context, output):
        output.SetFromVector(self.command(context.get_time()))
