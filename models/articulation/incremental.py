"""Incremental structure estimation as evidence arrives (thesis Sec. 4.4.1, Fig. 4.8, 4.9,
4.11, 4.17).

:class:`IncrementalStructure` collects synchronised observations of p parts one time step at
a time (NaN rows = part not observed) and re-selects the kinematic structure every
``refit_every`` steps from all data so far: pair models by BIC, then the graph search of
:mod:`mmlearn.models.articulation.graph` (``tree``, ``local`` or ``exhaustive``, optionally
with DOF reduction). The selected structure therefore changes as parts start moving: the
two-drawer cabinet is rigid(1,2) + prismatic(2,3) while only the lower drawer moves and
becomes prismatic(1,2) + prismatic(1,3) once both drawers move.

Each refit is recorded as an :class:`IncrementalStep` in ``history``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.graph import SEARCH_MODES, as_part_tracks, fit_structure
from mmlearn.models.articulation.structure import DEFAULT_CANDIDATES

__all__ = ["IncrementalStep", "IncrementalStructure", "incremental_structure"]


@dataclass
class IncrementalStep:
    """Structure selected after ``n`` time steps.

    Attributes:
        n: number of time steps seen.
        edges: [(part a, part b, model name)] with names of the parts.
        dof: object DOFs.
        bic: BIC of the selected graph.
        has_loop: closed chain selected.
        result: the full :class:`~mmlearn.models.articulation.graph.StructureResult`.
    """

    n: int
    edges: list
    dof: int
    bic: float
    has_loop: bool
    result: object

    def edge_set(self) -> set:
        return {(a, b, m) for a, b, m in self.edges}


class IncrementalStructure:
    """Structure learning from a stream of observations.

    Args:
        part_names: names of the p parts.
        models: candidate link models per pair.
        obs: observation noise model.
        search: "tree", "local" or "exhaustive".
        reduce_dofs: estimate object DOFs by PCA.
        refit_every: re-select the structure every this many time steps.
        min_observations: no structure before this many time steps with >= 2 parts.
        rng: Generator or seed.
    """

    def __init__(self, part_names, *, models=DEFAULT_CANDIDATES,
                 obs: ObservationModel | None = None, search: str = "tree",
                 reduce_dofs: bool = False, refit_every: int = 1, min_observations: int = 5,
                 n_hypotheses: int = 60, rng=None):
        self.part_names = list(part_names)
        if len(self.part_names) < 2:
            raise ValueError("need at least 2 parts")
        if search not in SEARCH_MODES:
            raise ValueError(f"unknown search {search!r}; choose from {', '.join(SEARCH_MODES)}")
        if int(refit_every) < 1:
            raise ValueError(f"refit_every must be >= 1, got {refit_every}")
        self.models = models
        self.obs = obs if obs is not None else ObservationModel()
        self.search = search
        self.reduce_dofs = bool(reduce_dofs)
        self.refit_every = int(refit_every)
        self.min_observations = max(3, int(min_observations))
        self.n_hypotheses = int(n_hypotheses)
        self.rng = np.random.default_rng(rng)
        self._rows = []
        self.history: list[IncrementalStep] = []

    @property
    def n(self) -> int:
        return len(self._rows)

    @property
    def current(self) -> IncrementalStep | None:
        return self.history[-1] if self.history else None

    def add(self, part_poses) -> IncrementalStep | None:
        """Add one time step ((p, 7) poses, NaN rows = unobserved). Returns the new step when
        the structure was re-selected, else None."""
        Y = np.asarray(part_poses, float)
        if Y.shape != (len(self.part_names), 7):
            raise ValueError(f"expected ({len(self.part_names)}, 7) poses, got {Y.shape}")
        self._rows.append(Y.copy())
        if self.n < self.min_observations or self.n % self.refit_every:
            return None
        return self.refit()

    def refit(self) -> IncrementalStep | None:
        """Re-select the structure from all data so far (None if not enough data yet)."""
        if self.n < 3:
            return None
        Yall = as_part_tracks(np.stack(self._rows, axis=1))
        try:
            r = fit_structure(Yall, part_names=self.part_names, search=self.search,
                              reduce_dofs=self.reduce_dofs, models=self.models, obs=self.obs,
                              rng=self.rng, min_common=self.min_observations,
                              n_hypotheses=self.n_hypotheses)
        except ValueError:
            return None
        b = r.best
        edges = [(self.part_names[i], self.part_names[j], b.models[(i, j)]) for i, j in b.edges]
        step = IncrementalStep(self.n, edges, int(b.dof), float(b.bic), bool(b.has_loop), r)
        self.history.append(step)
        return step


def incremental_structure(part_tracks, part_names=None, *, progress=None, **kw) -> list:
    """Feed (p, T, 7) observations one time step at a time into an
    :class:`IncrementalStructure` (``kw`` are its options) and return its history."""
    Y = as_part_tracks(part_tracks)
    names = list(part_names) if part_names is not None else [f"part{k}" for k in range(Y.shape[0])]
    inc = IncrementalStructure(names, **kw)
    for t in range(Y.shape[1]):
        inc.add(Y[:, t])
        if progress is not None:
            progress(t)
    return inc.history
