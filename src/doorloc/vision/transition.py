"""The width of an edge's transition: the blur (with the pixel) that sizes the readers' windows and shapes
the blurred-step fit (:func:`transition_width`).

The profiles of an edge's scan lines are aligned on their sub-pixel edge points, their gradients normalised
by their steps and averaged on a quarter-pixel grid, and the width is read off the mean gradient: from
its peak where it is wide, from its second moment near the edge where it is sharp (a few sub-pixel
phases make the peak spiky). Texture beside an edge adds to the step that normalises the gradients: on
the side of the edge that has none (the background beside a door), the mean gradient's half gives the
width without it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.jit import grey, kernel
from doorloc.vision.sampling import NO_LUT, oriented, pixel_buffer, warm_up_planes

__all__ = ["QUIET_REACH_SIGMAS", "blur_without_pixel", "narrowest_blur", "transition_width"]


def blur_without_pixel(transition_px: float) -> float:
    """The optical blur (Gaussian sigma, px) in a transition's RMS width: the pixel's own 1/12 px^2 taken out
    (0 where the width is unknown)."""
    return (
        math.sqrt(max(transition_px * transition_px - 1.0 / 12.0, 0.0))
        if math.isfinite(transition_px)
        else 0.0
    )


def narrowest_blur(widths: Iterable[float]) -> float:
    """The optical blur (px) in the narrowest of the finite transition ``widths`` (:func:`blur_without_pixel`;
    NaN where none is finite): one lens blurs every edge alike, and texture or a second structure only widens
    a transition."""
    ok = [w for w in widths if math.isfinite(w)]
    return blur_without_pixel(min(ok)) if ok else math.nan


def transition_width(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    lut: np.ndarray | None = None,
    quiet_side: int = 0,
) -> float:
    """RMS width (px) of the mean edge transition of the masked samples: the optical blur plus the pixel.

    The profiles are aligned on their sub-pixel edge, normalised by their step and averaged before
    the second moment of the gradient is taken, so noise averages out instead of inflating the width.
    ``quiet_side`` (+1: increasing ``along``, -1 decreasing, 0: neither) names the side without surface
    texture (the background beside a door): a wide transition's width is then also read from the mean
    gradient's half on that side (twice its area over the peak), which texture on the other side leaves
    alone, and the less of the two stands; from the whole window's step alone a grain line on the face a
    few px beyond the edge read as blur (1.3 px of blur measured as 2.4). (The less: a shadow or a second
    face on the background's side widens that half instead.) Returns NaN when no sample is usable.
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
            int(np.sign(quiet_side)),
        )
    )


#: the quiet side's half of the mean gradient is integrated this many (whole-step) widths from its peak
QUIET_REACH_SIGMAS = 3.0


@kernel(lambda k: k(np.array([0.0, 0.1, 0.3, 0.1, 0.0]), np.ones(5), -2, 0.3, -1, 3.0))
def _quiet_half_width(gm, filled, first_bin, peak, quiet, reach):
    """The Gaussian sigma (px) whose peak ``peak`` and half area match the mean gradient ``gm`` (bins of 1/4 px,
    bin ``q`` at ``(q + first_bin) / 4`` px; ``filled``: 1 where a profile fell) on the side ``quiet``
    (+-1) of its highest filled bin, out to ``reach`` px: ``2 area / (peak sqrt(2 pi))``, the area by the
    trapezoid over the filled bins (an edge along a pixel row fills one in four). Both peak and area carry
    the profiles' normalisation, which cancels. 0 where the side has no filled bin."""
    top = -1
    for q in range(gm.size):
        if filled[q] > 0 and (top < 0 or gm[q] > gm[top]):
            top = q
    if top < 0:
        return 0.0
    x0 = (top + first_bin) / 4.0
    area = 0.0
    x_prev = x0
    g_prev = gm[top]
    q = top + quiet
    n = 0
    while 0 <= q < gm.size:
        x = (q + first_bin) / 4.0
        if abs(x - x0) > reach:
            break
        if filled[q] > 0:
            area += 0.5 * (g_prev + gm[q]) * abs(x - x_prev)
            x_prev = x
            g_prev = gm[q]
            n += 1
        q += quiet
    if n == 0 or not area > 0:
        return 0.0
    return 2.0 * area / (peak * np.sqrt(2.0 * np.pi))


def _mean_transition_width_warm_up(k) -> None:
    for buf, table in warm_up_planes(16):
        for quiet in (0, -1):
            k(buf, 1, 16, 16, np.arange(6), np.full(6, 7.6), np.full(6, 100.0), 3, table, quiet)


@kernel(_mean_transition_width_warm_up)
def _mean_transition_width(buf, pitch_along, pitch_scan, n_along, scan, along, step, half, lut, quiet):
    """:func:`transition_width` of the profiles around ``along`` on ``scan`` (``step``: their steps), compiled.

    Each profile's gradient over ``[c0 - half, c0 + half]`` (``c0 = round(along)``, profiles leaving the
    image skipped), normalised to unit area, binned at 1/4 px relative to its sub-pixel edge; the bins'
    mean, smoothed over the filled bins, gives the width from its peak (or, below 1.5 px, from the second
    moment within 3 px); where ``quiet`` is +-1 and the peak says 1.5 px or more, the less of that and
    the width from the peak and the mean's area on that side of it (:func:`_quiet_half_width`). NaN when
    no profile is usable.
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
    if sigma >= 1.5 and quiet != 0:
        half_sigma = _quiet_half_width(gm, filled, lowest + lo_bin, peak, quiet, QUIET_REACH_SIGMAS * sigma)
        if 0 < half_sigma < sigma:
            sigma = half_sigma
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
