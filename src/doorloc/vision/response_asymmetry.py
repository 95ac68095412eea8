"""How far an edge's mean transition is from symmetric, and the exponent of the camera's response that makes
it least so: the measurement under :mod:`doorloc.vision.response`.

A plain step blurred by an even point-spread function has a symmetric transition in linear light; raw grey
levels raised to the wrong exponent skew it. :func:`asymmetry` measures that departure for many trial
exponents at once over the profiles across one edge (:class:`Transitions`), :func:`least_asymmetric` finds
the exponent where it is least (and any other about as good), and :func:`exponent_with_scatter` adds its
standard error from the scatter over blocks of scan lines. :func:`transition_skew_px` is the skew at one
exponent, in pixels (for the diagnostics).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import CubicSpline

from doorloc.vision.edges import DITHERING_NOISE_LEVELS
from doorloc.vision.jit import kernel, median_in_place, pairwise_sum, read_only
from doorloc.vision.response_plateaus import RESPONSE_LEVEL_ROWS, RESPONSE_PLATEAU_PX, plateau_level_rows

__all__ = [
    "RESPONSE_AMBIGUOUS_RATIO",
    "RESPONSE_GAMMA_RANGE",
    "RESPONSE_LEVEL_ROWS",
    "RESPONSE_PLATEAU_PX",
    "RESPONSE_SIGMA_FLOOR",
    "Transitions",
    "asymmetry",
    "dithered",
    "exponent_with_scatter",
    "least_asymmetric",
    "transition_skew_px",
]

#: exponents searched for the camera's response (a camera's gamma lies well inside)
RESPONSE_GAMMA_RANGE = (0.4, 5.0)
#: the smallest standard error of a line's exponent (8 blocks estimate a scatter to about +-25 %)
RESPONSE_SIGMA_FLOOR = 0.02
#: another exponent whose transition is within this factor as symmetric as the best one's is a second
#: reading of the same edge (:func:`least_asymmetric`)
RESPONSE_AMBIGUOUS_RATIO = 2.0
# the exponents every line is first read at (over RESPONSE_GAMMA_RANGE), and the factors about a line's
# exponent its blocks are read at (read-only: made once)
_RANGE_GRID = np.geomspace(*RESPONSE_GAMMA_RANGE, 25)
_BLOCK_GRID = np.geomspace(1 / 1.6, 1.6, 11)
_RANGE_GRID.flags.writeable = _BLOCK_GRID.flags.writeable = False
# the most distinct levels Transitions.levels indexes with 16 bits (more: numpy's own index)
_INDEX_LEVELS = 1 << 16


@dataclass(frozen=True)
class Transitions:
    """Raw profiles across one edge (full scale 1) and the edge's place in them, for the skew in ``g``.

    ``one_phase``: the edge points fall at one pixel phase (an edge along a pixel row or column), and
    :func:`asymmetry` reads the transition between the pixels by interpolation. ``dithered``: the
    plateaus' noise (half a grey level or more) dithers the rounding to grey levels, which then averages
    out over the profiles (:func:`least_asymmetric`).
    """

    raw: np.ndarray  # (N, 2 half + 1)
    offset: np.ndarray  # (N,) the window's first pixel centre minus the sub-pixel edge, px
    one_phase: bool = False
    dithered: bool = True
    #: the grey levels of full scale (255, 65535) where ``raw`` is whole grey levels over it; 0: not so
    top: float = 0.0

    def at_most(self, n: int) -> Transitions:
        """At most ``n`` of the profiles, evenly along the line (every k-th): enough for the shape."""
        if self.raw.shape[0] <= n:
            return self
        k = int(math.ceil(self.raw.shape[0] / n))
        return replace(self, raw=self.raw[::k], offset=self.offset[::k])

    @functools.cached_property
    def levels(self) -> tuple[np.ndarray, np.ndarray]:
        """The distinct raw levels (U,) and each pixel's index into them (N, W).

        A camera's profiles hold a few hundred grey levels (8 bits: at most 256) in thousands of pixels:
        :func:`asymmetry` and :func:`transition_skew_px` raise each level to each trial exponent once, not
        each pixel (an elementwise function of the level, so the same numbers). Made once per profiles,
        which :func:`asymmetry` reads four times or more. The index is 16-bit where the levels allow
        (always for 8- and 16-bit images): :func:`_normalised_profiles` reads it on every pixel for every
        exponent, a tenth faster than through numpy's 64-bit index.

        Where ``raw`` is whole grey levels over ``top`` (an 8- or 16-bit image's), the levels present are
        counted, not sorted: ``np.unique`` sorts the floats (~190 us for a line's 5000 pixels, ~25 for the
        count), and a level's place among those present is the count of those below it. The same arrays:
        ``k / top`` is the value ``raw`` holds for grey level ``k``, and increases with it.
        """
        if self.top > 0:
            grey = np.rint(self.raw * self.top).astype(np.intp)
            present = np.bincount(grey.ravel(), minlength=int(self.top) + 1) > 0
            place = np.cumsum(present) - 1
            return np.flatnonzero(present) / self.top, place.astype(np.uint16)[grey]
        levels, index = np.unique(self.raw, return_inverse=True)
        if levels.size <= _INDEX_LEVELS:
            index = index.astype(np.uint16)
        return levels, index.reshape(self.raw.shape)

    @functools.cached_property
    def level_rows(self) -> int:
        """The neighbouring profiles each side a profile's plateaus are averaged over
        (:func:`doorloc.vision.response_plateaus.plateau_level_rows`)."""
        return plateau_level_rows(self.raw, top=self.top)

    @functools.cached_property
    def log_levels(self) -> tuple[np.ndarray, np.ndarray]:
        """The distinct raw levels' logarithms (U,) and each pixel's index into them (N, W) (:attr:`levels`)."""
        levels, index = self.levels
        with np.errstate(divide="ignore"):
            return np.log(levels), index


def dithered(raw: np.ndarray, top: float) -> bool:
    """Whether raw profiles (full scale 1, ``top`` grey levels) have ``DITHERING_NOISE_LEVELS`` of noise or
    more on their plateaus (the median over the profiles of the end pixels' scatter about their mean)."""
    return bool(_plateau_scatter(raw, RESPONSE_PLATEAU_PX) * top >= DITHERING_NOISE_LEVELS)


def _plateau_scatter_warm_up(k) -> None:
    k(np.zeros((5, 12)), 3)


@kernel(_plateau_scatter_warm_up)
def _plateau_scatter(raw, pk):
    """The median over the profiles ``raw`` (N, W) of the standard deviation of their ``pk`` end pixels at
    each end about each end's mean (pooled, ``2 pk - 2`` degrees of freedom). Compiled: numpy's version
    made eight arrays for each line of every image (0.1 ms a line); the same numbers, its sums in its
    order (tests/vision/test_jit.py holds it to the numpy version in tests/vision/numpy_reference.py)."""
    N, W = raw.shape
    sd = np.empty(N)
    dev = np.empty(pk)
    for i in range(N):
        var = 0.0
        for o in (0, W - pk):
            mean = pairwise_sum(raw[i], o, pk) / pk
            for j in range(pk):
                d = raw[i, o + j] - mean
                dev[j] = d * d
            var += pairwise_sum(dev, 0, pk)
        sd[i] = math.sqrt(var / (2 * pk - 2))
    return median_in_place(sd)


def transition_skew_px(t: Transitions, rows: np.ndarray | slice, g: float) -> float:
    """The skew (50 % crossing minus centre of mass of the mean transition, px) of the profiles ``rows`` with
    raw levels raised to ``g``.

    The profiles' pixel differences, each normalised by its sum, are binned by their place along the edge
    (1/4 px bins, positions from the dark side to the bright one: the skew's sign then says which way the
    exponent is off, whichever the edge's polarity); bins no difference fell in are interpolated. NaN with
    fewer than 3 profiles that step, or a mean transition without a positive sum.
    """
    levels, index = t.levels  # each distinct level raised once, whichever rows are asked for
    return float(_skew(levels**g, index[rows], t.offset[rows]))


def _skew_warm_up(k) -> None:
    for dtype in (np.uint16, np.intp):  # Transitions.levels' two index types
        for offset in (np.zeros(5), np.zeros(10)[::2]):  # a line's offsets, whole or thinned
            k(np.linspace(0.1, 0.9, 3), np.zeros((5, 12), dtype), offset)


@kernel(_skew_warm_up)
def _skew(light, index, offset):
    """:func:`transition_skew_px` of the profiles ``light[index]`` (N, W) whose first pixel centres lie
    ``offset`` (N,) px from their edges. Compiled: numpy's version made a dozen arrays for each of the
    ~2 lines a realistic frame (0.27 ms); the same numbers, bit for bit: its pairwise sums, its bincount's
    order, np.interp's formula and np.searchsorted's bisection (tests/vision/test_jit.py holds it to the
    numpy version kept in tests/vision/numpy_reference.py)."""
    N, W = index.shape
    D = W - 1
    d = np.empty((N, D))
    tot = np.empty(N)
    good = np.zeros(N, np.bool_)
    bins = np.empty((N, D), np.int64)
    n_good = 0
    lo, hi = 1 << 62, -(1 << 62)  # the least and the largest bin of the profiles that step
    for i in range(N):
        for k in range(D):
            d[i, k] = light[index[i, k + 1]] - light[index[i, k]]
        tot[i] = pairwise_sum(d[i], 0, D)
        if not abs(tot[i]) > 1e-9:
            continue
        good[i] = True
        sign = 1.0 if tot[i] > 0 else -1.0
        for k in range(D):
            b = int(np.rint(((k + 0.5) + offset[i]) * sign * 4))
            bins[i, k] = b
            lo, hi = min(lo, b), max(hi, b)
        n_good += 1
    if n_good < 3:
        return np.nan
    n = hi - lo + 1
    acc = np.zeros(n)
    cnt = np.zeros(n, np.int64)
    for i in range(N):
        if good[i]:
            for k in range(D):
                j = bins[i, k] - lo
                acc[j] += d[i, k] / tot[i]
                cnt[j] += 1
    x = np.empty(n)
    for j in range(n):
        x[j] = (j + lo) / 4.0
    # np.interp over the filled bins (the first and the last are filled): a filled bin's own mean, an
    # empty one on the line between its filled neighbours, numpy's slope times the distance from the left
    gm = np.empty(n)
    left = 0
    for j in range(n):
        if cnt[j] > 0:
            gm[j] = acc[j] / cnt[j]
            left = j
        else:
            right = j + 1
            while cnt[right] == 0:
                right += 1
            f_left, f_right = acc[left] / cnt[left], acc[right] / cnt[right]
            slope = (f_right - f_left) / (x[right] - x[left])
            gm[j] = slope * (x[j] - x[left]) + f_left
    total = pairwise_sum(gm, 0, n)
    if total <= 0:
        return np.nan
    w = gm / total
    centre = pairwise_sum(w * x, 0, n)
    cum = np.cumsum(w) - 0.5 * w
    # np.searchsorted(cum, 0.5): its bisection (cum need not increase where the mean dips)
    a, b = 0, n
    while a < b:
        mid = a + ((b - a) >> 1)
        if cum[mid] < 0.5:
            a = mid + 1
        else:
            b = mid
    k = a
    if k <= 0 or k >= n:
        return np.nan
    den = cum[k] - cum[k - 1]
    den = 1e-12 if 1e-12 > den else den  # max(den, 1e-12) as Python takes it
    f = (0.5 - cum[k - 1]) / den
    return x[k - 1] + f * (x[k] - x[k - 1]) - centre


def exponent_with_scatter(
    t: Transitions, blocks: np.ndarray, n_blocks: int
) -> tuple[float, float, tuple[float, ...]] | None:
    """The exponent of least asymmetry of all the profiles ``t``, its standard error from the scatter of
    the exponents of the blocks (``blocks`` (N,): each profile's block), at least ``RESPONSE_SIGMA_FLOOR``,
    and the other exponents about as symmetric (:func:`least_asymmetric`); None where either of the first
    two is not found."""
    g_hat, alternatives = least_asymmetric(t, _RANGE_GRID)
    if not math.isfinite(g_hat):
        return None
    per_block = _least_asymmetric_blocks(t, g_hat * _BLOCK_GRID, blocks, n_blocks)
    per_block = per_block[np.isfinite(per_block)]
    if per_block.size < 3:
        return None
    se = float(np.std(per_block, ddof=1)) / math.sqrt(per_block.size)
    return g_hat, max(se, RESPONSE_SIGMA_FLOOR), alternatives


def asymmetry(
    t: Transitions, gammas: np.ndarray, blocks: np.ndarray | None = None, n_blocks: int = 0
) -> np.ndarray:
    """How far the profiles, with raw levels raised to each of ``gammas``, are from a step blurred by an
    even spread: shape ``(G,)``, or ``(G, n_blocks)`` over the rows of each block (``blocks`` (N,) the
    block of each profile).

    Each profile is normalised by its plateaus (the mean of ``RESPONSE_PLATEAU_PX`` pixels at each end,
    averaged over ``2 RESPONSE_LEVEL_ROWS + 1`` neighbouring scan lines: single noisy end pixels raised to
    the trial exponent would make the normalised noise, and so this measure's floor, depend on the
    exponent and pull its minimum; over fewer where the plateaus change from line to line,
    :attr:`Transitions.level_rows`) and centred on its own area estimate (exact for a pixel-integrated
    step under any even point-spread function); in linear light the pixel values at distances ``+d`` and
    ``-d`` from that centre then add up to 1. The measure is the mean square of that sum's departure
    from 1 over 1/8-px bins of ``d`` filled on both sides (NaN if fewer than 4 are, or fewer than 3
    profiles have two distinct plateaus).

    All exponents (and blocks) are evaluated in one call of a compiled kernel (:func:`_paired_asymmetry`,
    or :func:`_normalised_profiles` for :func:`_resampled_asymmetry`): this runs on every plain edge of
    every image.
    Blocks share the whole line's level smoothing. No shading tilt across the edge is taken out (see
    :func:`_plateaus`).
    """
    log_levels, index = t.log_levels
    light = np.exp(np.asarray(gammas, float)[:, None] * log_levels[None])  # (G, U): each level's light
    N = index.shape[0]
    size = min(2 * t.level_rows + 1, N)
    if t.one_phase:
        n, centre, good = _normalised_profiles(light, index, RESPONSE_PLATEAU_PX, size)
        return _resampled_asymmetry(n, centre, good, blocks, n_blocks)
    blk = blocks.astype(np.int64) if blocks is not None else np.zeros(N, dtype=np.int64)
    out = _paired_asymmetry(light, index, RESPONSE_PLATEAU_PX, size, blk, max(n_blocks, 1))
    return out if blocks is not None else out[:, 0]


# The two steps of asymmetry are compiled: written with numpy they were ~30 passes over (G, N, W) arrays
# of a few hundred kB, ~1.2 ms per call and 9 calls per edge-measuring image (11 ms of its ~27). The raw
# levels are raised to the exponents by numpy (its vectorised exp); the kernels give the numbers the
# numpy code gave, bit for bit: its sums in its order (numpy's pairwise sum along a row, scipy's running
# sum in uniform_filter1d), its median, its bincount (tests/vision/test_jit.py holds them to the numpy
# version kept in tests/vision/numpy_reference.py).


def _normalised_warm_up(k) -> None:
    for dtype in (np.uint16, np.intp):  # Transitions.levels' two index types
        k(np.full((2, 3), 0.5), np.zeros((5, 10), dtype), 3, 3)


@kernel(_normalised_warm_up)
def _normalised_profiles(light, index, pk, size):
    """:func:`asymmetry`'s profiles (light: raw levels raised to each exponent, ``light[g, index[i, w]]``
    for exponent ``g``, profile ``i``, pixel ``w``; the (G, N, W) array is never formed) normalised by
    their plateaus (``pk`` px at each end, averaged over ``size`` scan lines) over the inner
    ``L = W - 2 pk`` pixels: ``n`` (G, N, L), each profile's area centre (G, N, index units) and whether
    its plateaus differ (G, N).

    The levels' table and the index, not the (G, N, W) profiles: numpy's ``light[:, index]`` lays that array
    out with the exponent as its fastest axis, and this loop read it across the strides at twice the cost
    of the table's look-ups (and the gather itself was a fifth of :func:`asymmetry`). The same numbers."""
    G = light.shape[0]
    N, W = index.shape
    L = W - 2 * pk
    n = np.empty((G, N, L))
    centre = np.empty((G, N))
    good = np.zeros((G, N), dtype=np.bool_)
    ends = np.empty((2, N))
    row = np.empty(L)
    for g in range(G):
        lo, hi = _plateaus(light, g, index, pk, size, ends)
        for i in range(N):
            good[g, i], centre[g, i] = _normalised_row(light, g, index, i, pk, lo[i], hi[i], row)
            n[g, i, :] = row
    return n, centre, good


@kernel(inline=True)
def _plateaus(light, g, index, pk, size, ends):
    """The plateaus' levels of every profile at exponent ``g`` (:func:`_normalised_profiles`): the means
    of its ``pk`` end pixels, then over ``size`` neighbouring scan lines; ``ends`` (2, N) is scratch.

    No shading tilt is taken out: across a window of a few dozen pixels a cell's light or a lens's
    vignetting changes by well under a percent, while what does slope a plateau there is no shading: a
    lens's halo reaching beyond the window (its skirt slopes both plateaus alike in light), or texture
    and a far face's band on one side. Each plateau's relative slope, taken out as shading, had read a
    plain door's halo (a quarter of the light at 3.5x the blur) as a camera exponent of 2.13 +- 0.07 for
    its 1.21 and placed it 0.12 mm off at 7.7 sigma; the difference of the two plateaus' slopes over
    their levels', which a skirt cancels in, read a thin door's far-face band as shading instead (a
    linear camera read as 1.93 and absorbed)."""
    N, W = index.shape
    for e in range(2):
        o = 0 if e == 0 else W - pk
        for i in range(N):
            sm = 0.0
            for j in range(pk):
                sm += light[g, index[i, o + j]]
            ends[e, i] = sm / pk
    return _running_mean_nearest(ends[0], size), _running_mean_nearest(ends[1], size)


@kernel(inline=True)
def _normalised_row(light, g, index, i, pk, lo, hi, row):
    """Profile ``i`` at exponent ``g`` normalised by its plateaus ``lo``, ``hi`` into ``row`` (its inner
    ``L`` pixels: 0 on the first end, 1 on the last, any polarity); whether the plateaus differ, and
    the profile's area centre (index units: ``L - 1`` minus the trapezoid area of ``row``)."""
    L = row.size
    span = hi - lo
    good = abs(span) > 1e-9
    den = span if good else 1.0
    for k in range(L):
        row[k] = (light[g, index[i, pk + k]] - lo) / den
    return good, (L - 1) - (pairwise_sum(row, 0, L) - 0.5 * (row[0] + row[L - 1]))


def _paired_warm_up(k) -> None:
    for dtype in (np.uint16, np.intp):  # Transitions.levels' two index types
        k(np.full((2, 3), 0.5), np.zeros((5, 12), dtype), 3, 3, np.zeros(5, np.int64), 1)


@kernel(_paired_warm_up)
def _paired_asymmetry(light, index, pk, size, blocks, nb):
    """:func:`asymmetry`'s measure over each block of profiles (``blocks`` (N,) < ``nb``): (G, nb).

    The profiles are those of :func:`_normalised_profiles` (its arguments), each binned as it is
    normalised: the (G, N, L) array of them is never formed. The same numbers, summed in the same order
    (with the levels counted, :attr:`Transitions.levels`, 0.92 -> 0.87 ms a line on the realistic
    frames of ``bench/bench_speed.py --seed 11``). A profile whose plateaus do not differ is passed over
    before it is normalised, and the normalisation is written out here rather than called
    (:func:`_normalised_row` computes the same): the exponent's light row and the profile's index row are
    then taken once, and the bins of all blocks lie in one flat array (1.23 -> 1.14 ms a frame on those
    frames, the same numbers)."""
    G = light.shape[0]
    N, W = index.shape
    L = W - 2 * pk
    B = 4 * (L - 1)  # |d| * 8 never exceeds it inside the reach
    nbins = 2 * B + 1
    out = np.empty((G, nb))
    acc = np.zeros(nb * nbins)  # block b's bin j at b * nbins + j
    cnt = np.zeros(nb * nbins)  # (whole numbers: a division by them is the one by an integer count)
    rows_ok = np.zeros(nb)
    rr = np.empty(B)
    ends = np.empty((2, N))
    row = np.empty(L)
    reach = (L - 1) / 2.0 - 1.0
    for g in range(G):
        acc[:] = 0.0
        cnt[:] = 0.0
        rows_ok[:] = 0.0
        lo, hi = _plateaus(light, g, index, pk, size, ends)
        lg = light[g]
        for i in range(N):
            span = hi[i] - lo[i]
            if not abs(span) > 1e-9:
                continue
            ix = index[i]
            base = lo[i]
            for k in range(L):
                row[k] = (lg[ix[pk + k]] - base) / span
            centre = (L - 1) - (pairwise_sum(row, 0, L) - 0.5 * (row[0] + row[L - 1]))
            b = blocks[i]
            rows_ok[b] += 1.0
            o = b * nbins + B
            for k in range(L):
                d = k - centre
                if abs(d) <= reach:
                    at = int(np.rint(d * 8)) + o
                    acc[at] += row[k]
                    cnt[at] += 1.0
        for b in range(nb):
            m = 0
            o = b * nbins + B
            for k in range(B):
                cp, cn = cnt[o + 1 + k], cnt[o - 1 - k]  # bins at +d and -d, d = (k + 1) / 8
                if cp > 0 and cn > 0:
                    r = acc[o + 1 + k] / cp + acc[o - 1 - k] / cn - 1.0
                    rr[k] = r * r
                    m += 1
                else:
                    rr[k] = 0.0
            out[g, b] = pairwise_sum(rr, 0, B) / m if m >= 4 and rows_ok[b] >= 3 else np.nan
    return out


@kernel()
def _running_mean_nearest(x, size):
    """scipy.ndimage.uniform_filter1d(x, size, mode="nearest") as scipy computes it (a running sum over the
    line extended by its end values, each output the sum over ``size``)."""
    N = x.size
    out = np.empty(N)
    if N == 0:
        return out
    s1 = size // 2
    tot = 0.0
    for k in range(size):
        tot += x[min(max(k - s1, 0), N - 1)]
    out[0] = tot / size
    for i in range(1, N):
        tot += x[min(i + size - 1 - s1, N - 1)] - x[max(i - 1 - s1, 0)]
        out[i] = tot / size
    return out


def _resampled_asymmetry(
    n: np.ndarray, centre: np.ndarray, good: np.ndarray, blocks: np.ndarray | None, n_blocks: int
) -> np.ndarray:
    """:func:`asymmetry`'s measure where every profile samples the transition at one pixel phase.

    There the pixels at ``+d`` from the centre have no partners at ``-d``: the profiles of each block
    (normalised ``n`` (G, N, L), their area centres ``centre`` (G, N), ``good`` (G, N)) are averaged
    (their phases lie within a fraction of a pixel: the mean is the transition smoothed by an even spread,
    still symmetric in linear light) and the mean transition is read at ``centre +- d`` by a cubic spline
    through its pixels. The spline is exact enough only where the blur makes the transition smooth on the
    pixel scale (optical sigma 1 px and more: errors of a few per cent in the exponent on synthetic steps,
    up to a fifth at high exponents, where the measure is flat), so its readings carry a floor
    (``doorloc.vision.response.RESPONSE_ONE_PHASE_SIGMA``, ``RESPONSE_ONE_PHASE_CONTRAST``). A cubic
    spline and not a local kernel: on the same synthetic steps (exponents 1.0-2.2, blur 1.0-1.4 px, six
    phases) Keys' cubic convolution and a Lanczos-3 window misread the exponent by up to 0.6 and 2.0, the
    spline by up to 0.06 below 1.6 and 0.5 at 2.2. Same shapes and NaN rules as :func:`asymmetry`.
    """
    G, N, L = n.shape
    nb = max(n_blocks, 1)
    blk = blocks if blocks is not None else np.zeros(N, dtype=np.int64)
    onehot = np.zeros((N, nb))
    onehot[np.arange(N), blk] = 1.0
    w = good.astype(np.float64)
    cnt = w @ onehot  # (G, nb) profiles per group
    mean_n = np.einsum("gn,nb,gnl->gbl", w, onehot, np.where(good[:, :, None], n, 0.0))
    mean_c = np.einsum("gn,nb,gn->gb", w, onehot, np.where(good, centre, 0.0))
    ok = cnt >= 3
    mean_n = np.where(ok[:, :, None], mean_n / np.maximum(cnt, 1.0)[:, :, None], 0.0).reshape(G * nb, L)
    mean_c = np.where(ok, mean_c / np.maximum(cnt, 1.0), 0.0).reshape(G * nb)
    coef = CubicSpline(np.arange(L, dtype=np.float64), mean_n, axis=1).c  # (4, L - 1, G nb)
    d = np.arange(1, 4 * (L - 1) + 1) / 8.0
    d = d[d <= (L - 1) / 2.0 - 1.0]
    cols = np.arange(G * nb)[:, None]

    def at(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        inside = (x >= 0.0) & (x <= L - 1)
        i = np.clip(np.floor(x).astype(np.int64), 0, L - 2)
        u = x - i
        c = coef[:, i, cols]  # (4, G nb, D)
        return ((c[0] * u + c[1]) * u + c[2]) * u + c[3], inside

    fp, ip = at(mean_c[:, None] + d[None, :])
    fn, i_n = at(mean_c[:, None] - d[None, :])
    both = ip & i_n
    r = np.where(both, fp + fn - 1.0, 0.0)
    m = both.sum(axis=1)
    out = np.where((m >= 4) & ok.reshape(-1), (r * r).sum(axis=1) / np.maximum(m, 1), np.nan)
    return out.reshape(G, nb) if blocks is not None else out.reshape(G)


def _least_index_warm_up(k) -> None:
    k(np.array([1.0, np.nan, 0.5]))
    k(np.ones((3, 2))[:, 0])  # a block's column of _least_asymmetric_blocks' (G, n_blocks) table


@kernel(_least_index_warm_up)
def _least_index(a):
    """``np.nanargmin(a)`` where ``a`` has a finite value, else -1 (the first index of the least value that
    is not NaN: with a finite value present the least is finite, as nanargmin's NaN-as-infinity finds it).
    Compiled because :func:`_vertex` runs ~30 times per edge-measuring image, and nanargmin's masks and
    copies were half of its ~34 us."""
    best = -1
    finite = False
    for k in range(a.size):
        v = a[k]
        if not np.isnan(v) and (best < 0 or v < a[best]):
            best = k
        finite = finite or np.isfinite(v)
    return best if finite else -1


def _vertex_warm_up(k) -> None:
    grid = np.array([1.0, 1.1, 1.2])
    k(grid, np.array([1.0, 0.5, 0.7]))
    k(grid, np.ones((3, 2))[:, 0])  # a block's column of a (G, n_blocks) table
    k(read_only(grid), np.array([1.0, 0.5, 0.7]))  # least_asymmetric's finer grids (_refined_grid's cache)


@kernel(_vertex_warm_up)
def _vertex(grid, a):
    """The minimum of ``a`` over the increasing ``grid``: the vertex of the parabola (in ``log g``) through
    the least value and its two neighbours; the least grid value at an end or beside a NaN. Compiled
    (with :func:`_vertices`): it runs ~35 times a realistic frame, ~6 us each in Python; the same numbers
    (the logarithms and the exponential are libm's either way, and the clamps keep Python's ``min`` and
    ``max`` order)."""
    i = _least_index(a)
    if i < 0:
        return np.nan
    if i == 0 or i == grid.size - 1 or not (np.isfinite(a[i - 1]) and np.isfinite(a[i + 1])):
        return grid[i]
    # the parabola through three points in closed form (np.polyfit's least squares on three points is the
    # same curve at ~50x the cost)
    x0, x1, x2 = math.log(grid[i - 1]), math.log(grid[i]), math.log(grid[i + 1])
    y0, y1, y2 = a[i - 1], a[i], a[i + 1]
    s0, s2 = (y0 - y1) / (x0 - x1), (y2 - y1) / (x2 - x1)
    curv = (s2 - s0) / (x2 - x0)
    if curv <= 0:
        return grid[i]
    # slope at x1 of the parabola: s0 + curv (x1 - x0), so its vertex lies that over 2 curv before x1
    v = x1 - (s0 + curv * (x1 - x0)) / (2.0 * curv)
    v = x0 if x0 > v else v  # max(v, x0) as Python takes it (v unless x0 is larger), then min(., x2)
    v = x2 if x2 < v else v
    return math.exp(v)


def _vertices_warm_up(k) -> None:
    k(np.array([1.0, 1.1, 1.2]), np.ones((3, 2)))


@kernel(_vertices_warm_up)
def _vertices(grid, table):
    """:func:`_vertex` of each column of ``table`` (G, n) over ``grid`` (G,): (n,)."""
    out = np.empty(table.shape[1])
    for k in range(table.shape[1]):
        out[k] = _vertex(grid, table[:, k])
    return out


@functools.lru_cache(maxsize=64)
def _refined_grid(lo: float, hi: float) -> np.ndarray:
    """:func:`least_asymmetric`'s finer grid between two neighbours of its grid, made once per pair (the
    range grid has 25; read-only: the cache hands the same array out)."""
    fine = np.geomspace(lo, hi, 9)
    fine.flags.writeable = False
    return fine


def least_asymmetric(t: Transitions, grid: np.ndarray) -> tuple[float, tuple[float, ...]]:
    """The exponent of least :func:`asymmetry`: the best of ``grid``, then of a grid four times finer
    between its neighbours (steps of 2.7 % on the 25-point range grid), refined by a parabola: good to
    far below the exponent's standard error. And the other exponents (each refined alike) where the
    asymmetry has a minimum within ``RESPONSE_AMBIGUOUS_RATIO`` of the least, where the rounding to grey
    levels is not dithered by noise (``t.dithered``): there the least asymmetry is the rounding's, the
    same on every profile at one phase, and no measure of how well the two minima are told apart. Under
    noise the least is a noise floor that the comparison of the two minima averages: on noisy linear
    renders (1.2-2.8 grey levels) a second minimum at 2.2-2.5 came within 1.3-1.7 of the least, and
    the primary reading was the camera's every time.

    Why a second one: the asymmetry is not monotone in the exponent. Linearised with ``p`` times the
    camera's exponent, the transition's slope is the blur's spread weighted by the light raised to
    ``p - 1``, which for some ``p`` of about 2.5-3 (depending on the plateaus' ratio) is a spread shifted
    towards the bright side and again nearly symmetric. On a rendered 1.34 camera (plateaus 59 and 236
    grey levels, 1.7 px of blur) the asymmetry's two minima, at 1.38 and 3.6, differed by a factor 1.2 at
    16 bits, and at 8 bits without noise to dither the rounding (every pixel of a 1/8 px bin rounded
    alike) the false one at 2.25 was the lower: the cell's right exponent was replaced by it and the
    door placed 0.11 mm off at 8 sigma.
    """
    a = asymmetry(t, grid)
    i = int(_least_index(a))
    # (A least at an end of the range is kept as the line's reading, though it is no minimum: such a line
    # is skewed by texture or shading, and its disagreement with the other line's reading, skewed too, is
    # what keeps that one from sizing the response doubt alone. Taken as no reading (tried), a plain door
    # under grain through a linear camera, bench_surfaces.py --sets grain --seed 11 door 10, rested on its
    # reference arris's 2.94 +- 0.17 and was refused for a 0.145 mm response doubt, its answer 0.027 mm
    # off.)
    if i < 0:
        return float("nan"), ()

    def refined(i: int) -> float:
        lo, hi = max(i - 1, 0), min(i + 1, grid.size - 1)
        fine = _refined_grid(float(grid[lo]), float(grid[hi]))
        if t.one_phase:
            return float(_vertex(fine, asymmetry(t, fine)))
        # np.geomspace's ends are its arguments exactly, and each exponent's asymmetry on the paired path is
        # its own (the kernels loop over the exponents): the ends' values are the range grid's, read again
        af = np.empty(fine.size)
        af[1:-1] = asymmetry(t, fine[1:-1])
        af[0], af[-1] = a[lo], a[hi]
        return float(_vertex(fine, af))

    others = [
        j
        for j in range(1, grid.size - 1)
        if not t.dithered
        and abs(j - i) > 2
        and np.isfinite(a[j - 1 : j + 2]).all()
        and a[j] <= min(a[j - 1], a[j + 1])
        and a[j] <= RESPONSE_AMBIGUOUS_RATIO * a[i]
    ]
    return refined(i), tuple(g for g in (refined(j) for j in others) if math.isfinite(g))


def _least_asymmetric_blocks(
    t: Transitions, grid: np.ndarray, blocks: np.ndarray, n_blocks: int
) -> np.ndarray:
    """:func:`least_asymmetric` on each block of profiles (NaN where a block has no minimum)."""
    a = asymmetry(t, grid, blocks, n_blocks)  # (G, n_blocks)
    coarse = _vertices(grid, a)  # (NaN where a block has no finite value)
    found = coarse[np.isfinite(coarse)]
    if not found.size:
        return np.full(n_blocks, np.nan)
    step = grid[1] / grid[0]
    fine = np.geomspace(float(found.min()) / step, float(found.max()) * step, 21)
    per_block = _vertices(fine, asymmetry(t, fine, blocks, n_blocks))
    per_block[~np.isfinite(coarse)] = np.nan
    return per_block
