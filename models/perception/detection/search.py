"""Stages ``sampling`` and ``optimisation`` (thesis 5.1.2): greedy side moves on summed-area
tables, vectorised over all starts of all planes (:func:`_greedy_flat`), starts at the regions
between reveals (:func:`_component_starts`), and the in-plane rotation polish of accepted
rectangles (:func:`_polish_rotations`)."""

import math

import cv2
import numba
import numpy as np

from mmlearn.models.perception.detection.grid import (_Grid, _rect_camera, _rotate_axes, _sats,
                                                      _warp_labels)
from mmlearn.models.perception.detection.labels import IN_PLANE, OUTSIDE


# side moves on (x0, x1, y0, y1): grow left, shrink left, grow right, shrink right, same for y
_MOVES = np.array([[-1, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, -1, 0, 0],
                   [0, 0, -1, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, -1]], np.int64)


def _rect_sum(S, p, R):
    """Sums of the tables ``S[p]`` (stacked SATs) over rectangles R (..., 4) = x0 x1 y0 y1."""
    x0, x1, y0, y1 = R[..., 0], R[..., 1], R[..., 2], R[..., 3]
    _, H, W = S.shape
    flat = S.reshape(-1)  # one gather per corner on linear indices (same sums, faster)
    base = np.asarray(p) * (H * W)
    r0, r1 = base + y0 * W, base + y1 * W
    return (flat.take(r1 + x1) - flat.take(r0 + x1)) - (flat.take(r1 + x0) - flat.take(r0 + x0))


def _objective(SC, p, R, alpha):
    """g = sum(1 - cost) / n^(1 - alpha) over the rectangle's cells."""
    n = ((R[..., 1] - R[..., 0]) * (R[..., 3] - R[..., 2])).astype(np.float64)
    n = np.maximum(n, 1.0)
    return (n - _rect_sum(SC, p, R) * (1.0 / 255.0)) / n ** (1.0 - alpha)


@numba.njit(cache=True, nogil=True)
def _greedy_kernel(flat, base, stride, hw, R, steps, mc, alpha, max_iter, out_R, out_score):
    """The loop of :func:`_greedy_flat`, compiled: start by start, iteration by iteration, the
    moves in the order steps x _MOVES; writes out_R, out_score; returns the iterations used."""
    S, K = R.shape[0], steps.shape[1]
    e = 1.0 - alpha
    it_max = 0
    for s in range(S):
        x0, x1, y0, y1 = R[s, 0], R[s, 1], R[s, 2], R[s, 3]
        b, st, H, W, m = base[s], stride[s], hw[s, 0], hw[s, 1], mc[s]
        n = float(max((x1 - x0) * (y1 - y0), 1))
        v = ((flat[b + y1 * st + x1] + flat[b + y0 * st + x0])
             - (flat[b + y0 * st + x1] + flat[b + y1 * st + x0]))
        score = (n - v * (1.0 / 255.0)) / n ** e
        it, stopped = 0, False
        while it < max_iter:
            it += 1
            thr = score + 1e-12 * abs(score) + 1e-12
            best = -np.inf
            bx0 = bx1 = by0 = by1 = 0
            for k in range(K):
                sz = steps[s, k]
                for j in range(8):
                    a0, a1 = x0 + sz * _MOVES[j, 0], x1 + sz * _MOVES[j, 1]
                    c0, c1 = y0 + sz * _MOVES[j, 2], y1 + sz * _MOVES[j, 3]
                    if a0 < 0 or a1 > W or c0 < 0 or c1 > H or a1 - a0 < m or c1 - c0 < m:
                        continue  # not a legal rectangle
                    nn = float((a1 - a0) * (c1 - c0))
                    vv = ((flat[b + c1 * st + a1] + flat[b + c0 * st + a0])
                          - (flat[b + c0 * st + a1] + flat[b + c1 * st + a0]))
                    sc = (nn - vv * (1.0 / 255.0)) / nn ** e
                    if sc > best:  # (the first of equal ones)
                        best = sc
                        bx0, bx1, by0, by1 = a0, a1, c0, c1
            if not best > thr:
                stopped = True
                break
            x0, x1, y0, y1, score = bx0, bx1, by0, by1, best
        it_max = max(it_max, min(it + 1, max_iter) if stopped else max_iter)
        out_R[s, 0], out_R[s, 1], out_R[s, 2], out_R[s, 3] = x0, x1, y0, y1
        out_score[s] = score
    return it_max


def _greedy_flat(flat, base, stride, hw, R, steps, min_cells, alpha, max_iter):
    """Greedy side moves (steepest ascent of :func:`_objective`) for all starts, each on its
    own summed-area table of costs in one flat int32 buffer ``flat``: table of start i at
    ``base[i]`` with rows of ``stride[i]`` entries (the grid's width + 1); ``hw`` (S, 2) the
    grids' (H, W); R (S, 4) int rectangles x0 x1 y0 y1; steps (S, k) move sizes in cells;
    min_cells (S,). Each start moves each side by +-steps; the best legal move (inside the
    grid, both sides >= min_cells; the first of equal ones in the order steps x _MOVES) is
    taken while it improves the objective by more than 1e-12 (relative and absolute), at most
    ``max_iter`` times. Returns R (S, 4), objective (S,), iterations used (the most of any
    start, counting the one that found no improvement, at most ``max_iter``; 0 without starts).

    A compiled loop (:func:`_greedy_kernel`): a move's sum is four reads of its table, ~20 ns;
    the same moves and float64 objectives as numpy on the tables, 5x faster than the numpy
    version vectorised over starts (whose per-iteration array overhead dominated)."""
    R = np.ascontiguousarray(R, np.int64).reshape(-1, 4)
    out_R = R.copy()
    out_score = np.empty(len(R))
    if len(R) == 0:
        return out_R, out_score, 0
    it = _greedy_kernel(np.ascontiguousarray(flat), np.asarray(base, np.int64),
                        np.asarray(stride, np.int64), np.asarray(hw, np.int64).reshape(-1, 2), R,
                        np.asarray(steps, np.int64).reshape(len(R), -1),
                        np.asarray(min_cells, np.int64), float(alpha), int(max(0, max_iter)),
                        out_R, out_score)
    return out_R, out_score, int(it)


def _greedy(SC, dims, pid, R, steps, min_cells, alpha, max_iter):
    """Greedy side moves for all starts at once. SC: stacked cost SATs (P, Hm+1, Wm+1);
    dims (P, 2) grid shapes; pid (S,) plane of each start; R (S, 4) int rectangles; steps (S, k)
    move sizes in cells; min_cells (S,). Returns R, objective, iterations used
    (:func:`_greedy_flat` on the stack's flat buffer)."""
    _, Hs, Ws = SC.shape
    pid = np.asarray(pid, np.int64)
    R, score, it = _greedy_flat(SC.reshape(-1), pid * (Hs * Ws), np.full(len(pid), Ws, np.int64),
                                np.asarray(dims, np.int64)[pid], R, steps, min_cells, alpha,
                                max_iter)
    return R, score, it


def _stack(tables, dims):
    Hm = max(h for h, _ in dims) + 1
    Wm = max(w for _, w in dims) + 1
    out = np.zeros((len(tables), Hm, Wm), tables[0].dtype)
    for k, t in enumerate(tables):
        out[k, :t.shape[0], :t.shape[1]] = t
    return out


def _in_plane_cells(g: _Grid, r: np.ndarray) -> np.ndarray:
    """Flat indices of the ``r``-th in-plane cells of a grid in raster order (as
    ``np.flatnonzero(g.labels == IN_PLANE)[r]``): the row of each from the in-plane table's
    cumulative row totals, then a scan of that row only (not of the whole grid)."""
    rows = g.sat_in[1:, -1]  # in-plane cells in rows 0..i
    i = np.searchsorted(rows, r, side="right")
    out = np.empty(len(r), np.int64)
    for t in range(len(r)):
        before = int(rows[i[t] - 1]) if i[t] > 0 else 0
        cols = np.flatnonzero(g.labels[i[t]] == IN_PLANE)
        out[t] = int(i[t]) * g.shape[1] + int(cols[int(r[t]) - before])
    return out


_START_ERODE_CELLS = 3


def _component_starts(g: _Grid, mc: int, k: int, rng, cfg) -> np.ndarray:
    """Start rectangles (n, 4) at the centroid (if inside it) of each of the ``k`` largest
    4-connected regions of in-plane cells of a grid (at least ``mc`` x ``mc`` cells): fronts
    flush with their neighbours are one plane, parted only by ``GAP`` lines, and random
    starts over the whole plane miss a small drawer (5 % of a cabinet's face) often.
    Width and height from the prior, at most the region's bounding box."""
    # regions of the in-plane cells shrunk by _START_ERODE_CELLS (3) cells: a reveal's line
    # may have a hole of a few cells (where it meets another reveal, or a drop-out; a
    # horizontal reveal's run ends ~half a line window short of a T-junction with a vertical
    # one: 5 cells of 7.4 mm at 2.2 m, which joined a closed drawer's region to the door
    # below with 2 cells)
    r = _START_ERODE_CELLS
    inp = cv2.erode((g.labels == IN_PLANE).view(np.uint8),
                    np.ones((2 * r + 1, 2 * r + 1), np.uint8))
    n_lab, lab, stats, cent = cv2.connectedComponentsWithStats(inp, connectivity=4)
    if n_lab <= 1:
        return np.zeros((0, 4), np.int64)
    area = stats[1:, cv2.CC_STAT_AREA]
    mc = max(1, mc - 2 * r)
    big = np.flatnonzero((area >= mc * mc) & (stats[1:, cv2.CC_STAT_WIDTH] >= mc)
                         & (stats[1:, cv2.CC_STAT_HEIGHT] >= mc)) + 1
    if len(big) == 0:
        return np.zeros((0, 4), np.int64)
    big = big[np.argsort(-area[big - 1], kind="stable")][:k]
    # the region's centroid (inside a rectangular front), else a random cell of it
    cj = np.round(cent[big, 0]).astype(np.int64)
    ci = np.round(cent[big, 1]).astype(np.int64)
    for t in np.flatnonzero(lab[ci, cj] != big):
        cells = np.flatnonzero(lab.reshape(-1) == big[t])
        ci[t], cj[t] = divmod(int(cells[rng.integers(0, len(cells))]), lab.shape[1])
    m = len(big)
    wh = rng.uniform(cfg.prior_size[0], cfg.prior_size[1], (m, 2)) / g.c
    mc += 2 * r
    wc = np.clip(np.round(wh[:, 0]).astype(np.int64), mc,
                 np.maximum(mc, stats[big, cv2.CC_STAT_WIDTH]))
    hc = np.clip(np.round(wh[:, 1]).astype(np.int64), mc,
                 np.maximum(mc, stats[big, cv2.CC_STAT_HEIGHT]))
    Hg, Wg = g.shape
    x0 = np.clip(cj - wc // 2, 0, np.maximum(0, Wg - wc))
    y0 = np.clip(ci - hc // 2, 0, np.maximum(0, Hg - hc))
    return np.column_stack([x0, np.minimum(x0 + wc, Wg), y0, np.minimum(y0 + hc, Hg)])


def _polish_rotations(jobs, K, cfg, lut):
    """Rotate each rectangle in its plane about its centre by +-step_factors x
    rotation_step_deg; each rotation is followed by the side moves on the mask rectified at the
    new angle (a local window around the rectangle). The best improving rotation of a round is
    kept until none improves. ``jobs``: (grid, R, image label mask) per rectangle. Returns per
    job the objective and (e1, e2, u0, v0, R, labels, sat_cost, sat_in, c) of the window of the
    best angle.

    The rectangles are independent: the windows that all rectangles' current rounds need are
    rectified and moved in one batched greedy run (:func:`_greedy_flat`, each window on its own
    table: the same moves as rectangle by rectangle), round after round until every rectangle
    has stopped."""
    offsets = sorted({s * f * cfg.rotation_step_deg for f in cfg.rotation_step_factors
                      for s in (1, -1)})
    max_iter = int(cfg.max_iterations)
    states = []
    # the windows are rectified from each plane's cost image (its labels through the cost
    # table, made once per plane instead of once per window: the same cost cells); the label
    # window is made for each rectangle's best angle only
    cost_imgs = {}
    # the windows' cost tables of a round, in one buffer reused round after round (the
    # caches keep each window's result, not its table: ~25 MB of fresh pages per frame
    # otherwise)
    scratch = {}
    for g, R, lab_img in jobs:
        if id(lab_img) not in cost_imgs:
            cost_imgs[id(lab_img)] = cv2.LUT(lab_img, lut)
        states.append(_polish_job(g, R, lab_img, cost_imgs[id(lab_img)], offsets, cfg))
    step_max = max(offsets) if offsets else 0.0
    while True:
        todo = []
        for j in states:
            if not j["done"]:
                todo += [(j, t) for t in _wanted_angles(j, offsets, step_max)
                         if t not in j["cache"]]
        if todo:
            _fit_windows(todo, K, cfg, lut, scratch)
        live = False
        for j in states:
            _advance(j, offsets, max_iter)
            live |= not j["done"]
        if not live:
            break
    out = []
    for j in states:  # the best window's labels and tables, made again
        e1, e2, u0, v0, Rf = j["best"]
        g = j["g"]
        lab = _warp_labels(j["lab_img"], K, g.o, e1, e2, u0, v0, j["c"], (j["Hg"], j["Wg"]))
        out.append((j["best_score"], (e1, e2, u0, v0, Rf, lab) + _sats(lab, lut) + (j["c"],)))
    return out


def _polish_job(g, R, lab_img, cost_img, offsets, cfg) -> dict:
    """The state of one rectangle's rotation polish: its window on the plane (the recall
    margin plus room for the largest side move around it), the start in the window, the
    move sizes, the windows needed next (the start's and the first round's: fitted together,
    each window's moves are independent of the others'), the best so far."""
    c = g.c
    center, _, _, w, h = _rect_camera(g, R)
    steps_cells = sorted({max(1, int(round(f * cfg.step_size / c)))
                          for f in cfg.step_factors})  # (a list of ints)
    half = (max(cfg.recall_margin * max(w, h), cfg.min_recall_margin)
            + 2 * max(cfg.step_factors) * cfg.step_size)
    x0 = int(round(half / c))
    first = [round(o, 9) for o in offsets] if int(cfg.max_iterations) > 0 else []
    return dict(
        g=g, lab_img=lab_img, cost_img=cost_img, c=c, p=center - g.o, w=w, h=h, half=half,
        Wg=int(math.ceil((w + 2 * half) / c)), Hg=int(math.ceil((h + 2 * half) / c)),
        R0=np.array([x0, x0 + int(round(w / c)), x0, x0 + int(round(h / c))], np.int64),
        steps=steps_cells, min_cells=max(1, int(math.ceil(cfg.min_side / c))),
        cache={}, need=list(dict.fromkeys([0.0] + first)), theta=0.0, best=None,
        best_score=None, rounds=0, done=False, dir=0, streak=0)


def _wanted_angles(j, offsets, step_max) -> list:
    """The window angles a polish job needs next: its round's, and when it has turned the
    same way twice in a row (a front seen 10-20 deg rotated) also the next two rounds' should
    it go on by the largest step (a cache filled ahead: the same results, fewer rounds; at
    most 4 windows wasted per chain)."""
    want = j["need"]
    if j["streak"] >= 2:
        want = list(want)
        t = j["theta"]
        for _ in range(2):
            t = round(t + j["dir"] * step_max, 9)
            want += [round(t + o, 9) for o in offsets]
    return list(dict.fromkeys(want))


def _advance(j, offsets, max_iter) -> None:
    """In place: the rounds of a polish job whose windows are all fitted (its cache): the
    best improving rotation of a round is kept; the job is done when none improves or after
    ``max_iter`` rounds."""
    cache = j["cache"]
    while not j["done"] and all(t in cache for t in j["need"]):
        if j["best"] is None:  # the start's window
            j["best_score"], j["best"] = cache[0.0]
            if max_iter == 0:
                j["done"] = True
                return
        else:  # a round
            res = [cache[t] for t in j["need"]]
            i = int(np.argmax([r[0] for r in res]))
            j["rounds"] += 1
            if not res[i][0] > j["best_score"] + 1e-12 * abs(j["best_score"]):
                j["done"] = True
                return
            turn = 1 if j["need"][i] > j["theta"] else -1
            j["streak"] = j["streak"] + 1 if turn == j["dir"] else 1
            j["dir"] = turn
            j["best_score"], j["best"], j["theta"] = res[i][0], res[i][1], j["need"][i]
            if j["rounds"] >= max_iter:
                j["done"] = True
                return
        j["need"] = [round(j["theta"] + o, 9) for o in offsets]


def _fit_windows(todo, K, cfg, lut, scratch=None):
    """The windows (job state, angle in deg) of :func:`_polish_rotations`: each rectified,
    its cost table written into one flat buffer, all moved in one greedy run; results
    (objective, (e1, e2, u0, v0, R)) into the jobs' caches. ``scratch``: a dict whose
    ``"buf"`` (int32) is reused when large enough (and replaced by a larger one if not)."""
    dims = np.array([(j["Hg"], j["Wg"]) for j, _ in todo], np.int64)
    sizes = (dims[:, 0] + 1) * (dims[:, 1] + 1)
    base = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    total = int(sizes.sum())
    scratch = {} if scratch is None else scratch
    buf = scratch.get("buf")
    if buf is None or len(buf) < total:
        buf = scratch["buf"] = np.empty(total, np.int32)
    buf = buf[:total]
    wins = []
    for (j, t), b0, sz in zip(todo, base, sizes):
        g, c = j["g"], j["c"]
        e1, e2 = _rotate_axes(g.e1, g.e2, math.radians(t))
        u0 = j["p"] @ e1 - 0.5 * j["w"] - j["half"]
        v0 = j["p"] @ e2 - 0.5 * j["h"] - j["half"]
        Hg, Wg = j["Hg"], j["Wg"]
        cost = _warp_labels(j["cost_img"], K, g.o, e1, e2, u0, v0, c, (Hg, Wg),
                            outside=lut[OUTSIDE])
        # the window's cost table written straight into the buffer (no copy)
        cv2.integral(cost, buf[b0:b0 + sz].reshape(Hg + 1, Wg + 1), sdepth=cv2.CV_32S)
        wins.append((e1, e2, u0, v0))
    kmax = max(len(j["steps"]) for j, _ in todo)
    # each window's move sizes, padded with its last (np.pad's "edge"; on lists: ~10 us less
    # per window)
    steps = np.array([j["steps"] + j["steps"][-1:] * (kmax - len(j["steps"]))
                      for j, _ in todo], np.int64)
    Rf, sc, _ = _greedy_flat(buf, base, dims[:, 1] + 1, dims, np.array([j["R0"] for j, _ in todo]),
                             steps, np.array([j["min_cells"] for j, _ in todo], np.int64),
                             cfg.alpha, cfg.max_iterations)
    for i, (j, t) in enumerate(todo):
        j["cache"][t] = (float(sc[i]), wins[i] + (Rf[i],))
