"""The coarse step finder of the locate pipeline, written for speed.

:func:`coarse_edges` gives exactly what the first, plainer finder gave (kept as the reference in
tests/vision/coarse_reference.py): the same arrays, bit for bit (the same float32 sums in the same
order). It is one compiled pass over each scan line (:mod:`doorloc.vision.jit`): the profile read
straight from the image's buffer, the step response from integer window sums (8-bit images) or a float32
running sum, the in-image test on the interval bounds, the strongest (or preferred) step kept; the array
version it replaced built a dozen (scan lines, samples) arrays for that.
The speed matters because this runs three times on every image before anything is known about it.
"""

from __future__ import annotations

import numpy as np

from doorloc.vision.jit import kernel, read_only, select_kth
from doorloc.vision.lines import ImageLine, ransac_line
from doorloc.vision.sampling import Axis, oriented, pixel_buffer

__all__ = ["coarse_edges"]


def coarse_edges(
    plane: np.ndarray,
    axis: Axis,
    scan: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    polarity: int,
    half: int = 3,
    prefer: np.ndarray | None = None,
    prefer_fraction: float = 0.3,
    stride: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Strongest step of the given polarity on each scan line between ``lo`` and ``hi``.

    The step response at ``k`` is the mean of ``half`` pixels after ``k`` minus the mean of ``half``
    pixels before it, which finds blurred edges and ignores single noisy pixels.

    Parameters
    ----------
    plane : ndarray (H, W)
        Luminance.
    axis : "col" or "row"
    scan : ndarray (N,) int
        Scan-line coordinates (in the image).
    lo, hi : ndarray (N,) int
        Search interval on each scan line (inclusive), px.
    polarity : +1, -1 or 0
        +1: the edge goes dark to bright with increasing ``along``; 0: either way.
    half : int
        Half-width of the step detector, px.
    prefer : ndarray (N,) float, optional
        Expected edge position per scan line: instead of the strongest step, take the local maximum
        nearest to it among those at least ``prefer_fraction`` of the strongest (e.g. the far arris,
        next to which a visible far face makes a second, stronger step).
    stride : int
        Look at every ``stride``-th pixel along the scan line only (a coarse answer, ``stride`` px
        resolution, for a fraction of the work); ``half`` counts strided samples.

    Returns
    -------
    along : ndarray (N,) float
        Edge position (pixel boundary between the two halves, i.e. ``k - 0.5``), NaN if none.
    strength : ndarray (N,) float
        Step response there, grey levels of the plane (signed by polarity, so >0 is the right way).
    """
    # why many parameters: the coarse stage's queries are keyword dicts of exactly these names (batched.py replays them per image, tests/vision/coarse_reference.py takes the same), so the names are the query's format
    scan = np.asarray(scan, int)
    lo = np.asarray(lo, int) - half * stride
    hi = np.asarray(hi, int) + half * stride
    n = scan.size
    length = int(np.max(hi - lo)) // stride + 1 if n else 0
    if n == 0 or length <= 2 * half + 1:
        return np.full(n, np.nan), np.zeros(n)
    P = oriented(plane, axis)
    buf, pitch_along, pitch_scan = pixel_buffer(P)
    return _strongest_steps(
        buf,
        pitch_along,
        pitch_scan,
        P.shape[0],
        scan,
        lo,
        hi,
        length,
        stride,
        half,
        int(polarity),
        plane.dtype == np.uint8 and half <= 4096,
        np.asarray(prefer, float) if prefer is not None else _NO_PREFER,
        prefer is not None,
        float(prefer_fraction),
    )


_NO_PREFER = np.zeros(0)


@kernel()
def _nearest_peak(resp, thr, lo, stride, half, prefer):
    """The local maximum of ``resp`` (at least ``thr`` and > 0) whose step lies nearest ``prefer`` (the first
    of equally near ones): ``(position, a NaN distance was met)``; position -1 where none."""
    pick = -1
    pick_d = np.inf
    nan_seen = False
    for t in range(1, resp.size - 1):
        r = resp[t]
        if r >= resp[t - 1] and r > resp[t + 1] and r >= thr and r > 0:
            d = abs((lo + stride * (t + half) - 0.5 * stride) - prefer)
            if d != d:
                nan_seen = True
            elif d < pick_d:
                pick, pick_d = t, d
    return pick, nan_seen


def _strongest_steps_warm_up(k) -> None:
    img = np.zeros((16, 16), np.uint8)
    img[:, 8:] = 100
    for buf in (img.reshape(-1), img.astype(np.uint16).reshape(-1)):
        for prefer in (_NO_PREFER, np.full(4, 8.0)):
            for scan in (np.arange(4), read_only(np.arange(4))):  # (the finder's cached scan lines)
                k(
                    buf,
                    16,
                    1,
                    16,
                    scan,
                    np.full(4, 1),
                    np.full(4, 14),
                    14,
                    1,
                    2,
                    1,
                    buf.dtype == np.uint8,
                    prefer,
                    prefer.size > 0,
                    0.3,
                )


@kernel(_strongest_steps_warm_up)
def _strongest_steps(
    buf,
    pitch_along,
    pitch_scan,
    n_along,
    scan,
    lo,
    hi,
    length,
    stride,
    half,
    polarity,
    exact_int,
    prefer,
    use_prefer,
    prefer_fraction,
):
    """The search of :func:`coarse_edges` on each scan line, compiled (:mod:`doorloc.vision.jit`).

    ``lo``, ``hi``: the intervals already widened by ``half * stride``; profile ``i`` is
    ``buf[clamp(lo[i] + stride k) * pitch_along + scan[i] * pitch_scan]`` for ``k < length``. The same
    float32 numbers as the array code this replaced, bit for bit (tests/vision/test_coarse.py holds it
    to the first finder, tests/vision/coarse_reference.py): integer window sums for 8-bit images, else
    differences of a float32 running sum; ties to the first position.
    """
    # why many parameters: a numba nopython kernel reading the image buffer by its pitches (no array view or dataclass crosses into nopython code): the buffer, its layout, the scan lines' intervals and the search's settings pass one by one
    # why long: the profiles are gathered in the buffer's order and searched in the same compiled loop; split, the (N, length) profiles would cross a call boundary per image and the window sums are held bit for bit against tests/vision/coarse_reference.py
    n = scan.size
    m = length - 2 * half + 1
    along = np.full(n, np.nan)
    strength = np.zeros(n, np.float32)
    # every profile first, read in the buffer's order (down columns, row after row across the scan lines:
    # neighbouring columns share cache lines; one column after another would miss the cache at every pixel)
    V = np.empty((n, length), buf.dtype)
    if pitch_along > pitch_scan:
        for j in range(length):
            for i in range(n):
                jj = min(max(lo[i] + stride * j, 0), n_along - 1)
                V[i, j] = buf[jj * pitch_along + scan[i] * pitch_scan]
    else:
        for i in range(n):
            for j in range(length):
                jj = min(max(lo[i] + stride * j, 0), n_along - 1)
                V[i, j] = buf[jj * pitch_along + scan[i] * pitch_scan]
    c = np.zeros(length + 1, np.float32)
    win = np.empty(length - half + 1, np.int64)
    resp = np.empty(m, np.float32)
    mag = np.empty(m, np.float32)
    neg_inf = np.float32(-np.inf)
    fhalf = np.float32(half)
    for i in range(n):
        v = V[i]
        if exact_int:
            # win[t] = v[t] + ... + v[t + half - 1]; the difference of two such integers (< 2**24) is
            # exact in float32
            acc = 0
            for u in range(half):
                acc += v[u]
            win[0] = acc
            for t in range(1, length - half + 1):  # (integers: the running sum is exact)
                acc += np.int64(v[t + half - 1]) - np.int64(v[t - 1])
                win[t] = acc
            for t in range(m):
                resp[t] = np.float32(win[t + half]) - np.float32(win[t])
        else:
            for j in range(length):
                c[j + 1] = c[j] + np.float32(v[j])
            for t in range(m):
                mid = c[t + half]
                resp[t] = (c[t + 2 * half] - mid) - (mid - c[t])
        # usable detector positions: samples in the image and in [lo, hi]
        ja = max(-(lo[i] // stride), 0)
        jb = min(min((n_along - 1 - lo[i]) // stride, (hi[i] - lo[i]) // stride), length - 1)
        ub = jb if jb >= length - 1 else jb - 2 * half + 1
        best = 0
        for t in range(m):
            r = resp[t]
            if polarity == 0:
                r = abs(r)
            elif polarity != 1:
                r = r * np.float32(polarity)
            r = r / fhalf
            resp[t] = r if (t >= ja and t <= ub) else neg_inf
            if resp[t] > resp[best]:
                best = t
        if use_prefer:
            # the local maximum nearest the preferred position among those of at least prefer_fraction of
            # the strongest and 5 noise floors (1.4826 x the median |response| over the line, 0 where not
            # usable); a NaN preference prefers nothing
            low = np.float32(prefer_fraction) * resp[best]
            total = 0.0
            for t in range(m):
                mag[t] = abs(resp[t]) if resp[t] != neg_inf else np.float32(0.0)
                total += mag[t]
            pick, nan_seen = _nearest_peak(resp, low, lo[i], stride, half, prefer[i])
            # The median needs a selection over the line; a pick at least 5 x 1.4826 x twice the mean
            # |response| (the median of values >= 0 is at most twice their mean) passes the floor without it
            # (with a margin for the float32 products): the nearest above the lower threshold is then the
            # nearest above both.
            if pick >= 0 and not nan_seen and not resp[pick] >= 14.826 * (total / m) * (1.0 + 1e-6):
                k = m // 2
                select_kth(mag, k)
                if m % 2:
                    med = mag[k]
                else:
                    below = mag[0]
                    for t in range(1, k):
                        below = max(below, mag[t])
                    med = (below + mag[k]) / np.float32(2.0)
                thr = max(low, np.float32(5.0) * (np.float32(1.4826) * med))
                if thr > low:
                    pick, nan_seen = _nearest_peak(resp, thr, lo[i], stride, half, prefer[i])
            if pick >= 0 and not nan_seen:
                best = pick
        s = resp[best]
        if np.isfinite(s):
            strength[i] = s
            along[i] = lo[i] + stride * (best + half) - 0.5 * stride
    return along, strength


def line_through_steps(
    scan: np.ndarray,
    along: np.ndarray,
    strength: np.ndarray,
    thr: float,
    min_points: int,
    min_fraction: float,
) -> ImageLine | None:
    """The RANSAC line (3 px tolerance) through the scan lines' steps of at least ``thr``, or None without
    ``min_points`` such steps or ``min_fraction`` of the scan lines on it."""
    strong = np.isfinite(along) & (strength >= thr)
    line = ransac_line(scan[strong], along[strong], 3.0) if strong.sum() >= min_points else None
    if line is not None and line.inliers.sum() >= min_fraction * max(len(scan), 1):
        return line
    return None
