"""The phases and the immutable state of :class:`~mmlearn.systems.articulation.epc_controller.
EpcController` (thesis Sec. 4.3): the controller's abstract state is an :class:`EpcState`
that every update replaces (``dataclasses.replace``), never changes in place."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

__all__ = ["DRIVE", "PREHOOK", "DEPTH", "SLIDE", "PULL", "RELEASE", "DONE", "PHASE_NAMES",
           "EpcState", "EpcInputs"]

DRIVE, PREHOOK, DEPTH, SLIDE, PULL, RELEASE, DONE = range(7)
PHASE_NAMES = ["drive", "prehook", "depth", "slide", "pull", "release", "done"]


@dataclass(frozen=True)
class EpcState:
    """The controller's state (its abstract state), immutable: every update makes a new one
    with :func:`dataclasses.replace`; its arrays are read-only copies (of the arrays it is
    given; a replace shares the old state's own). Drake may therefore share it between
    contexts instead of copying it.

    Attributes:
        phase: the current phase (DRIVE .. DONE).
        t_phase: time the phase began, s.
        q_from, q_to: the command interpolated over one period from ``q_from`` (at
            ``t_cmd``) to ``q_to``.
        t_cmd: time of the last command, s.
        start: where the phase began (the commands in DRIVE, the grip point after it).
        R: the hook's commanded orientation while pulling.
        cep: the equilibrium point of the pull (world, m).
        direction: the pull's current direction (unit).
        q_hat0, q_hat: the learned model's configuration at the pull's start and now.
        opening: the opening by the learned model (rad or m).
        model_name: the kind of the learned model in use ("" before one).
        stalled, stall_G: periods held back, and the grip point when the stall began.
        trail_G, motion: the handle's direction of motion over its last ``motion_window``.
        slack: consecutive periods without force on the hook.
        last_G: the grip point at the last update.
        side_extra: the side offset's correction by retries, m.
        bar_depth: depth at which the bar was met (NaN: not yet), m.
        retries: retries of the hooking so far.
        grip: the point of the hook that holds the handle, in the hook's body frame (m;
            empty: the seat, ``P_HOOK_GRIP``; the finger's tip when the slide ended on a
            knob's stem).
        outcome: why the pull ended ("" while it goes on).
    """

    phase: int = DRIVE
    t_phase: float = 0.0
    q_from: np.ndarray = field(default_factory=lambda: np.zeros(0))
    q_to: np.ndarray = field(default_factory=lambda: np.zeros(0))
    t_cmd: float = 0.0
    start: np.ndarray = field(default_factory=lambda: np.zeros(0))  # phase start (q or G)
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    cep: np.ndarray = field(default_factory=lambda: np.zeros(3))
    direction: np.ndarray = field(default_factory=lambda: np.zeros(3))
    q_hat0: float = float("nan")
    q_hat: float = float("nan")
    opening: float = 0.0
    model_name: str = ""
    stalled: int = 0
    stall_G: np.ndarray = field(default_factory=lambda: np.zeros(3))
    trail_G: np.ndarray = field(default_factory=lambda: np.zeros(3))
    motion: np.ndarray = field(default_factory=lambda: np.zeros(3))
    slack: int = 0
    last_G: np.ndarray = field(default_factory=lambda: np.zeros(3))
    side_extra: float = 0.0
    bar_depth: float = float("nan")
    retries: int = 0
    outcome: str = ""
    grip: np.ndarray = field(default_factory=lambda: np.zeros(0))

    _ARRAYS = ("q_from", "q_to", "start", "R", "cep", "direction", "stall_G", "trail_G",
               "motion", "last_G", "grip")

    def __post_init__(self):
        for k in self._ARRAYS:
            v = getattr(self, k)
            if (isinstance(v, np.ndarray) and v.dtype == np.float64 and v.flags.owndata
                    and not v.flags.writeable):
                continue  # a state's own read-only copy (kept by ``replace``): shared as is
            v = np.array(v, dtype=float)
            v.setflags(write=False)
            object.__setattr__(self, k, v)

    def __deepcopy__(self, memo):
        return self  # immutable: a copy would equal it


class EpcInputs(NamedTuple):
    """What a control period sees: time, time since the phase began (s), the wrist force
    (world, N) and the measured grip point (world, m)."""

    t: float
    elapsed: float
    F: np.ndarray
    G: np.ndarray
