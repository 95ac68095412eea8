"""The plateaus a camera-response reading normalises each profile across an edge by: how many pixels at
each end, and over how many neighbouring scan lines they are averaged (:func:`plateau_level_rows`, for
:func:`doorloc.vision.response_asymmetry.asymmetry`). Units: raw levels, full scale 1.
"""

from __future__ import annotations

import numpy as np

from doorloc.vision.jit import kernel, median_in_place

__all__ = ["RESPONSE_LEVEL_ROWS", "RESPONSE_PLATEAU_PX", "plateau_level_rows"]

#: plateau pixels at each end of a profile that set its levels, and the scan lines (each side) they are
#: averaged over
RESPONSE_PLATEAU_PX = 3
RESPONSE_LEVEL_ROWS = 8
#: the scan lines each side tried where the plateaus differ from profile to profile, and the growth of
#: their miss from 1 to ``RESPONSE_LEVEL_ROWS`` lines each side beyond which they are taken to (noise
#: alone shrinks it)
_LEVEL_ROWS_TRIED = (0, 1, 2, 4, RESPONSE_LEVEL_ROWS)
_ACROSS_TEXTURE_GROWTH = 2.0
#: the median of a squared standard normal variable: a median of squares over it estimates a variance
_MEDIAN_OF_CHI2_1 = 0.454936
_ROWS_AVERAGED = np.array(_LEVEL_ROWS_TRIED[1:], np.int64)
_ROWS_AVERAGED.flags.writeable = False


def plateau_level_rows(raw: np.ndarray, pk: int = RESPONSE_PLATEAU_PX, top: float = 0.0) -> int:
    """How many neighbouring profiles (each side) the plateaus of each profile of ``raw`` (N, W; in scan-line
    order) are averaged over in :func:`doorloc.vision.response_asymmetry.asymmetry`:
    ``RESPONSE_LEVEL_ROWS``, unless the plateaus differ from profile to profile, then the number of
    ``_LEVEL_ROWS_TRIED`` whose average misses each profile's own plateaus least.

    Why: the average keeps single noisy end pixels, raised to the trial exponent, from making the
    measure's floor depend on the exponent; but where the surface's light changes from one scan line to
    the next (grain across the edge: stripes along the scan lines), the average misses each line's own
    plateau by the texture's change over the lines, and that miss, raised to each trial exponent, is the
    floor the least asymmetry then follows. On a plain bottom end under grain along the door's height
    (camera doors bench, seed 73000, door 21: a 2.11 camera, grain 9 %) the end read 0.76 +- 0.08 with
    the plateaus averaged over 8 lines each side, 1.77 +- 0.13 over the 1 chosen here.

    Each end's plateau (the mean of its ``pk`` pixels) is compared with the mean of its neighbours' over
    ``R`` lines each side: with noise alone that miss's mean square is ``s2 (1 + 1 / 2R)`` (``s2`` the
    plateau's own noise variance, from its pixels' scatter, at least the rounding's where ``top`` gives
    the grey levels of full scale) and falls with ``R``; texture across the lines makes it grow. Where
    it grows by ``_ACROSS_TEXTURE_GROWTH`` or more from 1 to ``RESPONSE_LEVEL_ROWS`` lines at either end,
    and beyond that many times what noise alone leaves over 1 line (``1.5 s2``: undithered 8-bit
    plateaus hold one level on most lines, where the miss over 1 line is 0), each ``R`` tried is scored
    by the error its average leaves, summed over both ends: ``s2 / (2R + 1)`` of noise and the
    texture's part of the miss (its mean square less the noise's) scaled to the average that includes
    the line itself; ``R = 0`` leaves ``s2``. The miss's mean square is taken as the median of the
    squares over the lines (over the median of a squared normal variable): something else in a few
    lines' plateaus (a distractor crossing the window) is no texture that those lines' own plateaus
    would follow (read on its own lines, it had moved the clean renders' readings: a linear camera's
    bottom end from 1.16 to 3.28). Noise alone (or the slow change of a blur tail with the edge's pixel
    phase, which a line's neighbours share) does not pass the first test, and the plateaus are averaged
    as before."""
    N = raw.shape[0]
    if N < 2 * RESPONSE_LEVEL_ROWS + 1:
        return RESPONSE_LEVEL_ROWS
    rounding = 1.0 / (12.0 * top * top) if top > 0 else 0.0
    s2, miss = _plateau_misses(raw, pk, rounding, _ROWS_AVERAGED)  # (2,), (2, K): R = 1, 2, 4, 8
    if not np.any(miss[:, -1] > _ACROSS_TEXTURE_GROWTH * np.maximum(miss[:, 0], 1.5 * s2)):
        return RESPONSE_LEVEL_ROWS
    # each count's error left, summed over both ends: noise only for R = 0; else the noise averaged and
    # the texture's part of the miss, scaled to the average that includes the line itself
    R = _ROWS_AVERAGED
    texture = np.maximum(miss - s2[:, None] * (1 + 1 / (2 * R)), 0.0)
    left = (s2[:, None] / (2 * R + 1) + (2 * R / (2 * R + 1)) ** 2 * texture).sum(axis=0)
    return _LEVEL_ROWS_TRIED[int(np.concatenate([[s2.sum()], left]).argmin())]


def _misses_warm_up(k) -> None:
    raw = np.linspace(0.1, 0.9, 40 * 9).reshape(40, 9)
    for profiles in (raw, raw[::2]):  # a line's profiles, whole or thinned (fit_line_response)
        k(profiles, 3, 0.0, _ROWS_AVERAGED)


@kernel(_misses_warm_up)
def _plateau_misses(raw, pk, rounding, rows):
    """Each end's plateau noise variance ``s2`` (2,) (the mean over the profiles of its ``pk`` pixels'
    variance, at least ``rounding``, over ``pk``) and the mean square of each profile's plateau's miss
    against the mean of its neighbours' over each of ``rows`` lines each side, as the median of the
    squares over ``_MEDIAN_OF_CHI2_1`` (2, K): :func:`plateau_level_rows`'s figures. Compiled: in numpy
    they were ~0.1-0.2 ms a line (a dozen small arrays, two medians per row count), read on every
    plain edge of every image."""
    N, W = raw.shape
    K = rows.size
    s2 = np.empty(2)
    out = np.empty((2, K))
    m = np.empty(N)
    c = np.empty(N + 1)
    sq = np.empty(N)
    for e in range(2):
        o = 0 if e == 0 else W - pk
        spread = 0.0
        for i in range(N):
            level = 0.0
            for j in range(pk):
                level += raw[i, o + j]
            level /= pk
            m[i] = level
            v = 0.0
            for j in range(pk):
                d = raw[i, o + j] - level
                v += d * d
            spread += v / (pk - 1)
        s2[e] = max(spread / N, rounding) / pk
        c[0] = 0.0
        for i in range(N):
            c[i + 1] = c[i] + m[i]
        for k in range(K):
            r = rows[k]
            for i in range(N):
                lo, hi = max(i - r, 0), min(i + r + 1, N)
                d = m[i] - (c[hi] - c[lo] - m[i]) / (hi - lo - 1)
                sq[i] = d * d
            out[e, k] = median_in_place(sq) / _MEDIAN_OF_CHI2_1
    return s2, out
