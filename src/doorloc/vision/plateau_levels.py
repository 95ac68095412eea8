"""How many scan lines an edge's plateau levels are averaged over along it (:func:`level_smoothing`), for
the area estimator of :mod:`doorloc.vision.edges`.

Levels in the plane's units; scan lines in order along the edge.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.vision.jit import kernel

__all__ = ["LEVEL_STRUCTURE_RATIO", "LEVEL_STRUCTURE_SHIFT_PX", "level_smoothing", "running_level_mean"]

#: a plateau's levels whose departure from their running mean along the edge exceeds this many times what
#: their noise makes, and moves the edge points by more than ``LEVEL_STRUCTURE_SHIFT_PX`` (px RMS), change
#: along the edge: texture crosses it (:func:`level_smoothing`)
LEVEL_STRUCTURE_RATIO = 4.0
LEVEL_STRUCTURE_SHIFT_PX = 0.05


@kernel(inline=True)
def running_level_mean(x, inside, k):
    """``x`` averaged over ``k`` scan lines each side (running float32 sums, as np.cumsum of float32 levels;
    a profile not ``inside`` the image or NaN takes no part)."""
    n = x.size
    cs = np.zeros(n + 1)
    cnt = np.zeros(n + 1, np.int64)
    run = np.float32(0.0)
    for i in range(n):
        if inside[i] and np.isfinite(x[i]):
            run += np.float32(x[i])
            cnt[i + 1] = cnt[i] + 1
        else:
            cnt[i + 1] = cnt[i]
        cs[i + 1] = run
    y = np.empty(n)
    for i in range(n):
        lo = max(i - k, 0)
        hi = min(i + k + 1, n)
        y[i] = (cs[hi] - cs[lo]) / max(cnt[hi] - cnt[lo], 1)
    return y


def _level_smoothing_warm_up(k) -> None:
    k(np.ones(20), np.ones(20, np.bool_), np.zeros(20, np.int64), 10, 3, 50.0, 1.0)


@kernel(_level_smoothing_warm_up)
def level_smoothing(x, inside, start, level_smooth, half, step, quantum):
    """The scan lines each side over which one plateau's levels ``x`` (N, in order along the edge) are
    averaged: ``level_smooth``, unless the levels change along the edge in a way their noise does not explain.

    Averaging along the edge takes the noise out of a plateau's level, which is right where the surface
    beside the edge is uniform along it (a plain face, shading, grain running along the edge). Where
    texture crosses the edge (wood grain along the door's height at its bottom end, a knot, a stain, a
    shadow's border) each scan line's level is its own, and the average puts its neighbours' under it: on
    doors with 20 % grain across the bottom end the edge points swung +-1 px with the stripes and valid
    doors were refused ``edge_not_straight``. So the levels' mean square departure from their running mean
    over the scan lines whose windows start at the same pixel (``start``) is compared with what their noise
    makes (from their third differences along the edge, where texture of a few pixels' period or more
    hardly shows, and a grey level's rounding, ``quantum`` in the plane's units). Within such a run a level
    read beside texture that runs along the edge holds still; where the window steps to the next pixel it
    steps with it, which is no texture across the edge (on a nearly noise-free door the steps alone had
    passed the test and the reference arris lost its points at the corner). Beyond
    ``LEVEL_STRUCTURE_RATIO`` times that noise, and moving the edge points by more than
    ``LEVEL_STRUCTURE_SHIFT_PX`` (the area estimator's lever on a level: ``half + 1/2`` over the edge's
    ``step``, the plane's units), the averaging is the one of ``level_smooth``, its halves, .. and 0 that
    leaves the level the least expected error (the departure beyond the noise, plus the noise the average
    leaves). Profiles not ``inside`` the image take no part.
    """
    if level_smooth <= 0 or not step > 0:
        return level_smooth
    n = x.size
    # the levels taken, and the noise of one scan line's level: a third difference of white noise has 20
    # times its variance (one pass over the plateau: this runs on both plateaus of every plain line). Second
    # differences had let stripes of 15 lines' period through at 17 % of their swing: 30 grey levels of
    # stripes read as 1.6 grey of noise, which the averaging then seemed to take out, and the stripes'
    # bias was kept (0.10 px RMS where each line's own levels gave 0.08); a third difference passes 7 %.
    n_ok = 0
    sq3 = 0.0
    n3 = 0
    for i in range(n):
        if inside[i] and np.isfinite(x[i]):
            n_ok += 1
        if 0 < i < n - 2 and inside[i - 1] and inside[i] and inside[i + 1] and inside[i + 2]:
            d3 = x[i + 2] - 3.0 * x[i + 1] + 3.0 * x[i] - x[i - 1]
            if np.isfinite(d3):
                sq3 += d3 * d3
                n3 += 1
    if n3 < 8:
        return level_smooth
    noise = sq3 / n3 / 20.0 + quantum * quantum / 12.0
    sq_run, left_run = _within_runs(x, inside, start, level_smooth, noise)
    structure_run = max(sq_run - left_run, 0.0) / n_ok
    if sq_run <= LEVEL_STRUCTURE_RATIO * left_run or (
        math.sqrt(structure_run) * (half + 0.5) / step <= LEVEL_STRUCTURE_SHIFT_PX
    ):
        return level_smooth
    best_k = level_smooth
    best = np.inf
    k = level_smooth
    while True:
        if k > 0:
            y = running_level_mean(x, inside, k)
            sq = 0.0
            for i in range(n):
                if inside[i] and np.isfinite(x[i]):
                    sq += (y[i] - x[i]) ** 2
            departure = sq / n_ok
            left = noise * (1.0 - 1.0 / (2 * k + 1))  # what the noise alone departs by
            structure = max(departure - left, 0.0)
            expected = structure + noise / (2 * k + 1)
        else:
            expected = noise
        if expected < best:
            best, best_k = expected, k
        if k == 0:
            return best_k
        k //= 2


@kernel(inline=True)
def _within_runs(x, inside, start, k, noise):
    """The levels' summed square departure from their running mean over ``k`` lines each side within their
    run (the contiguous scan lines whose windows start at the same pixel), and what a level ``noise``
    (variance) alone makes of it. Prefix sums: this runs on both plateaus of every plain line."""
    n = x.size
    cs = np.zeros(n + 1)
    cnt = np.zeros(n + 1, np.int64)
    for i in range(n):
        ok = inside[i] and np.isfinite(x[i])
        cs[i + 1] = cs[i] + (x[i] if ok else 0.0)
        cnt[i + 1] = cnt[i] + (1 if ok else 0)
    last = np.empty(n, np.int64)  # the last line of each line's run
    for i in range(n - 1, -1, -1):
        last[i] = last[i + 1] if i + 1 < n and start[i + 1] == start[i] else i
    sq_run = 0.0
    left_run = 0.0
    first = 0  # the first line of the current run
    for i in range(n):
        if i > 0 and start[i] != start[i - 1]:
            first = i
        if not (inside[i] and np.isfinite(x[i])):
            continue
        a, b = max(i - k, first), min(i + k, last[i]) + 1
        m = cnt[b] - cnt[a]
        sq_run += ((cs[b] - cs[a]) / m - x[i]) ** 2
        left_run += noise * (1.0 - 1.0 / m)
    return sq_run, left_run
