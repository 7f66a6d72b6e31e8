"""The front detector's greedy side moves (thesis 5.1.2) and rotation polish: the vectorised
greedy (corner indices and legality slacks kept in a per-start state,
tables of any row length in one flat buffer) takes the same moves as a plain move-by-move
greedy on direct sums of the cost grid; the rotation polishes of several rectangles run
together give what each gives alone."""

import math

import cv2
import numpy as np
import pytest

from mmlearn.models.perception.detection import FrontDetectorConfig, Plane
from mmlearn.models.perception.detection.grid import _make_grid
from mmlearn.models.perception.detection.labels import FREE, IN_PLANE, OCCLUDED, UNKNOWN
from mmlearn.models.perception.detection.search import (_greedy, _greedy_flat, _MOVES,
                                                         _polish_rotations, _stack)
from mmlearn.models.common.camera import PinholeIntrinsics

ALPHA = 0.05


def _naive(cost, R, steps, mc, alpha, max_iter):
    """Move by move: every side +- every step, legal when inside the grid and both sides
    >= mc; objective (n - sum(cost) / 255) / n^(1 - alpha) from the grid itself; the first
    best move while it improves by more than 1e-12 (relative and absolute)."""
    H, W = cost.shape

    def score(r):
        x0, x1, y0, y1 = r
        n = max(float((x1 - x0) * (y1 - y0)), 1.0)
        s = int(cost[y0:y1, x0:x1].astype(np.int64).sum()) if x1 > x0 and y1 > y0 else 0
        return (n - s * (1.0 / 255.0)) / n ** (1.0 - alpha)

    r = [int(v) for v in R]
    cur = score(r)
    for _ in range(max_iter):
        best, best_r = -math.inf, None
        for s in steps:
            for mv in _MOVES:
                c = [a + int(s) * int(b) for a, b in zip(r, mv)]
                x0, x1, y0, y1 = c
                if not (0 <= x0 <= W and 0 <= x1 <= W and 0 <= y0 <= H and 0 <= y1 <= H
                        and x1 - x0 >= mc and y1 - y0 >= mc):
                    continue
                v = score(c)
                if v > best:
                    best, best_r = v, c
        if best_r is None or not best > cur + 1e-12 * abs(cur) + 1e-12:
            break
        r, cur = best_r, best
    return r, cur


def _random_problem(rng, P=3):
    costs = [rng.choice(np.array([0, 20, 255], np.uint8), size=tuple(rng.integers(2, 40, 2)),
                        p=[0.6, 0.2, 0.2]) for _ in range(P)]
    # a block of in-plane cells in each (something to grow into)
    for c in costs:
        h, w = c.shape
        c[h // 4: 3 * h // 4, w // 4: 3 * w // 4] = 0
    return costs


@pytest.mark.parametrize("seed", range(6))
def test_greedy_equals_moves_on_direct_sums(seed):
    """Random cost grids (3 planes of different shapes, some narrower than min_cells), random
    starts (some not legal rectangles: narrower than min_cells), two step sets, iteration
    limits: the same rectangles and objectives as the plain greedy."""
    rng = np.random.default_rng(seed)
    costs = _random_problem(rng)
    dims = np.array([c.shape for c in costs], np.int64)
    SC = _stack([cv2.integral(c, sdepth=cv2.CV_32S) for c in costs], [c.shape for c in costs])
    S = 40
    pid = rng.integers(0, len(costs), S)
    H, W = dims[pid].T
    x0, y0 = rng.integers(0, W), rng.integers(0, H)
    R = np.column_stack([x0, np.minimum(W, x0 + rng.integers(0, 15, S)), y0,
                         np.minimum(H, y0 + rng.integers(0, 15, S))])
    steps = np.array([[1, 2, 4, 8] if i % 2 else [1, 3, 3, 3] for i in range(S)], np.int64)
    mc = rng.integers(1, 6, S)
    for max_iter in (0, 3, 200):
        Rg, sg, _ = _greedy(SC, dims, pid, R, steps, mc, ALPHA, max_iter)
        for i in range(S):
            r, sc = _naive(costs[pid[i]], R[i], steps[i], mc[i], ALPHA, max_iter)
            assert Rg[i].tolist() == r, (max_iter, i)
            assert sg[i] == pytest.approx(sc, rel=1e-15, abs=1e-15)


def test_greedy_flat_tables_of_any_stride():
    """Tables of different widths packed one after another in one flat buffer (the rotation
    polish's windows) give what each table gives on its own."""
    rng = np.random.default_rng(7)
    costs = _random_problem(rng, P=4)
    sats = [cv2.integral(c, sdepth=cv2.CV_32S) for c in costs]
    base = np.cumsum([0] + [s.size for s in sats[:-1]])
    flat = np.concatenate([s.ravel() for s in sats])
    dims = np.array([c.shape for c in costs], np.int64)
    R = np.array([[c.shape[1] // 2 - 1, c.shape[1] // 2 + 1, c.shape[0] // 2 - 1,
                   c.shape[0] // 2 + 1] for c in costs], np.int64)
    steps = np.tile([1, 2, 4], (len(costs), 1))
    mc = np.full(len(costs), 2)
    Rf, sf, _ = _greedy_flat(flat, base, dims[:, 1] + 1, dims, R, steps, mc, ALPHA, 200)
    for i, s in enumerate(sats):
        Ri, si, _ = _greedy(s[None], dims[i:i + 1], np.zeros(1, np.int64), R[i:i + 1],
                            steps[i:i + 1], mc[i:i + 1], ALPHA, 200)
        assert np.array_equal(Rf[i], Ri[0])
        assert sf[i] == si[0]


def _tilted_fronts():
    """A label image of a plane 2 m in front of the camera with three fronts (rotated 0, 2
    and -3 deg in the image) on a free background, some drop-outs and an occluder."""
    K = PinholeIntrinsics.from_fov(640, 480, 58.0)
    lab = np.full((K.height, K.width), FREE, np.uint8)
    for (cx, cy, w, h, ang) in ((170, 150, 150, 110, 0.0), (430, 160, 180, 120, 2.0),
                                (300, 350, 220, 90, -3.0)):
        box = cv2.boxPoints(((cx, cy), (w, h), ang)).astype(np.int32)
        cv2.fillConvexPoly(lab, box, IN_PLANE)
    rng = np.random.default_rng(2)
    lab[rng.random(lab.shape) < 0.02] = UNKNOWN
    lab[330:370, 280:290] = OCCLUDED
    z = 2.0
    vv, uu = np.mgrid[4:K.height:8, 4:K.width:8]
    pts = np.column_stack([((uu - K.cx) / K.fx * z).ravel(), ((vv - K.cy) / K.fy * z).ravel(),
                           np.full(uu.size, z)])
    plane = Plane(n=np.array([0.0, 0.0, -1.0]), d=z, support=len(pts),
                  bbox=(0, K.height // 8 - 1, 0, K.width // 8 - 1))
    return K, lab, pts, plane


def test_polish_rotations_batched_equals_one_by_one():
    """The rotation polishes of several rectangles run together (one greedy run per round
    over all their new windows) give each rectangle's own result: objective, axes, window
    origin, rectangle and tables."""
    cfg = FrontDetectorConfig()
    K, lab, pts, plane = _tilted_fronts()
    lut = np.zeros(256, np.uint8)
    lut[:7] = np.round(255.0 * np.array([cfg.cost_in_plane, cfg.cost_free, cfg.cost_occluded,
                                         cfg.cost_unknown, cfg.cost_free, cfg.cost_unknown,
                                         cfg.cost_free]))
    g = _make_grid(0, plane, lab, pts, K, np.array([0.0, 1.0, 0.0]), cfg, lut)
    assert g is not None
    # greedy rectangles from a start inside each front
    starts = []
    for (u, v) in ((170, 150), (430, 160), (300, 350), (120, 110)):
        p = np.array([(u - K.cx) / K.fx * 2.0, (v - K.cy) / K.fy * 2.0, 2.0]) - g.o
        j, i = int((p @ g.e1 - g.u0) / g.c), int((p @ g.e2 - g.v0) / g.c)
        starts.append([j - 5, j + 5, i - 5, i + 5])
    n = len(starts)
    R, _, _ = _greedy(g.sat_cost[None], np.array([g.shape]), np.zeros(n, np.int64),
                      np.array(starts, np.int64), np.tile([1, 2, 4, 8], (n, 1)),
                      np.full(n, 6), cfg.alpha, cfg.max_iterations)
    jobs = [(g, R[i], lab) for i in range(n)]
    together = _polish_rotations(jobs, K, cfg, lut)
    turned = 0
    for job, (score, best) in zip(jobs, together):
        alone_score, alone = _polish_rotations([job], K, cfg, lut)[0]
        assert score == alone_score
        e1, e2, u0, v0, Rf, labels, sat_cost, sat_in, c = best
        assert np.array_equal(e1, alone[0]) and np.array_equal(e2, alone[1])
        assert (u0, v0, c) == (alone[2], alone[3], alone[8])
        assert np.array_equal(Rf, alone[4]) and np.array_equal(labels, alone[5])
        assert np.array_equal(sat_cost, alone[6]) and np.array_equal(sat_in, alone[7])
        turned += abs(float(e1 @ g.e1)) < math.cos(math.radians(0.25))
    assert turned >= 1  # the tilted fronts turned the rectangles (not a vacuous polish)


def test_polish_rotations_no_rounds():
    """max_iterations 0: each rectangle keeps its window at angle 0 (no round runs)."""
    cfg = FrontDetectorConfig(max_iterations=0)
    K, lab, pts, plane = _tilted_fronts()
    lut = np.zeros(256, np.uint8)
    lut[1] = 255
    g = _make_grid(0, plane, lab, pts, K, np.array([0.0, 1.0, 0.0]), cfg, lut)
    R = np.array([10, 30, 10, 30], np.int64)
    (score, best), = _polish_rotations([(g, R, lab)], K, cfg, lut)
    assert np.array_equal(best[0], g.e1) and np.isfinite(score)


def test_in_plane_cells_equal_flatnonzero():
    """The r-th in-plane cells found from the in-plane table's row totals are those of
    np.flatnonzero on the whole grid (random grids, every rank, rows without in-plane
    cells)."""
    from mmlearn.models.perception.detection.grid import _Grid, _sats
    from mmlearn.models.perception.detection.search import _in_plane_cells

    rng = np.random.default_rng(5)
    for shape in ((1, 1), (7, 3), (40, 57)):
        labels = rng.choice(np.array([IN_PLANE, FREE, UNKNOWN], np.uint8), size=shape,
                            p=[0.3, 0.5, 0.2])
        labels[shape[0] // 2] = FREE  # a row without in-plane cells
        labels.reshape(-1)[0] = IN_PLANE
        lut = np.zeros(256, np.uint8)
        sat_cost, sat_in = _sats(labels, lut)
        g = _Grid(0, np.zeros(3), 0.0, np.zeros(3), np.zeros(3), np.zeros(3), 0.0, 0.0, 0.01,
                  labels, sat_cost, sat_in)
        cells = np.flatnonzero(labels.reshape(-1) == IN_PLANE)
        r = np.arange(len(cells))
        assert np.array_equal(_in_plane_cells(g, r), cells)
        assert int(sat_in[-1, -1]) == len(cells)
