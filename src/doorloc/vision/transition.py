"""The width of an edge's transition: the blur (with the pixel) that sizes the readers' windows and shapes
the blurred-step fit (:func:`transition_width`).

The profiles of an edge's scan lines are aligned on their sub-pixel edge points, their gradients normalised
by their steps and averaged on a quarter-pixel grid, and the width is read off the mean gradient: from
its peak where it is wide, from its second moment near the edge where it is sharp (a few sub-pixel
phases make the peak spiky).
"""

from __future__ import annotations

import numpy as np

from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.jit import grey, kernel
from doorloc.vision.sampling import NO_LUT, oriented, pixel_buffer, warm_up_planes

__all__ = ["transition_width"]


def transition_width(
    plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int, lut: np.ndarray | None = None
) -> float:
    """RMS width (px) of the mean edge transition of the masked samples: the optical blur plus the pixel.

    The profiles are aligned on their sub-pixel edge, normalised by their step and averaged before
    the second moment of the gradient is taken, so noise averages out instead of inflating the width.
    Returns NaN when no sample is usable.
    """
    m = mask & samples.valid
    if not np.any(m):
        return float("nan")
    P = oriented(plane, samples.axis)
    flat = pixel_buffer(P)
    return float(
        _mean_transition_width(
            *flat,
            P.shape[0],
            samples.scan[m],
            samples.along[m],
            samples.step[m].astype(np.float64),
            half,
            lut if lut is not None else NO_LUT,
        )
    )


def _mean_transition_width_warm_up(k) -> None:
    for buf, table in warm_up_planes(16):
        k(buf, 1, 16, 16, np.arange(6), np.full(6, 7.6), np.full(6, 100.0), 3, table)


@kernel(_mean_transition_width_warm_up)
def _mean_transition_width(buf, pitch_along, pitch_scan, n_along, scan, along, step, half, lut):
    """:func:`transition_width` of the profiles around ``along`` on ``scan`` (``step``: their steps), compiled.

    Each profile's gradient over ``[c0 - half, c0 + half]`` (``c0 = round(along)``, profiles leaving the
    image skipped), normalised to unit area, binned at 1/4 px relative to its sub-pixel edge; the bins'
    mean, smoothed over the filled bins, gives the width from its peak (or, below 1.5 px, from the second
    moment within 3 px). NaN when no profile is usable.
    """
    # why many parameters: a numba nopython kernel over the plane's flat buffer takes arrays and scalars only
    # why long: binning, the bins' smoothed peak and the second moment share one compiled pass's arrays
    n = scan.size
    L = 2 * half + 1
    row = np.empty(L)
    g = np.empty(L - 1)
    # bins: pos * 4 for pos in [-half - 1, half + 1]: offsets 0 .. 8 half + 8 from the lowest
    n_bins = 8 * half + 9
    acc = np.zeros(n_bins)
    cnt = np.zeros(n_bins, np.int64)
    lo_bin = 4 * (-half - 1)
    lowest = n_bins
    any_ok = False
    for i in range(n):
        c0 = np.rint(along[i])
        start = int(c0) - half
        if start < 0 or start + L - 1 >= n_along:
            continue
        any_ok = True
        base = scan[i] * pitch_scan
        for j in range(L):
            v = buf[(start + j) * pitch_along + base]
            row[j] = grey(lut, v)
        gsum = 0.0
        for j in range(L - 1):
            g[j] = (np.float32(row[j + 1]) - np.float32(row[j])) / step[i]
            gsum += g[j]
        den = max(abs(gsum), 1e-6)
        sgn = np.sign(gsum)
        for j in range(L - 1):
            pos = j + 0.5 - half + (c0 - along[i])
            b = int(np.rint(pos * 4.0)) - lo_bin
            acc[b] += g[j] / den * sgn
            cnt[b] += 1
            lowest = min(lowest, b)
    if not any_ok:
        return np.nan
    # the bins from the lowest filled one up (as np.bincount from the minimum)
    highest = 0
    for b in range(n_bins):
        if cnt[b] > 0:
            highest = b
    m = highest - lowest + 1
    gm = np.zeros(m)
    filled = np.zeros(m)
    for q in range(m):
        if cnt[lowest + q] > 0:
            gm[q] = acc[lowest + q] / cnt[lowest + q]
            filled[q] = 1.0
    peak = -np.inf
    for q in range(m):
        sg = gm[q]
        sf = filled[q]
        if q > 0:
            sg += gm[q - 1]
            sf += filled[q - 1]
        if q < m - 1:
            sg += gm[q + 1]
            sf += filled[q + 1]
        peak = max(peak, sg / max(sf, 1.0))
    if not peak > 0:
        return np.nan
    sigma = 1.0 / (peak * np.sqrt(2.0 * np.pi))
    if sigma < 1.5:
        # A sharp edge sampled at few sub-pixel phases makes a spiky mean gradient whose peak says little:
        # the second moment within +-3 px instead (the tails, where noise lives, excluded).
        wsum = 0.0
        mom = 0.0
        for q in range(m):
            x = (q + lowest + lo_bin) / 4.0
            if abs(x) <= 3.0:
                wsum += gm[q]
                mom += gm[q] * x
        if wsum > 0:
            mu = mom / wsum
            var = 0.0
            for q in range(m):
                x = (q + lowest + lo_bin) / 4.0
                if abs(x) <= 3.0:
                    var += gm[q] * (x - mu) ** 2
            sigma = np.sqrt(max(var / wsum, 0.0))
    return sigma
