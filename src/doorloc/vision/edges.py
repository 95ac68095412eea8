"""Edge points along integer scan lines: a coarse step finder and a sub-pixel area estimator.

Every profile runs along an image column (for a near-horizontal edge, ``axis="col"``) or an image
row (near-vertical edge, ``axis="row"``), so no interpolation blurs the data. The edges of this
product are within a few degrees of the image axes; a column profile gives the edge position at
the column's centre exactly even for a slanted edge, because the pixel values integrate the edge
over the column width.

Sub-pixel estimator
-------------------
A camera pixel integrates light over its area, so a straight edge appears as a box-filtered step,
possibly blurred further by the lens. For such a profile ``I(k) = A + (B - A) F(k)`` the sum of
``F`` over a window equals the length of the window on the far side of the edge, exactly, whatever
the blur (as long as the window holds the whole transition). Hence

    e = k1 + 1/2 - sum_{k0..k1} (I(k) - A) / (B - A)

with ``A``, ``B`` the mean levels on plateaus just outside the window. This "area" (first-moment)
estimator is unbiased for box-filtered and blurred steps, unlike a parabola through three gradient
samples (biased by up to ~0.05 px on sharp edges), and a linear shading across the edge cancels
when the window is centred on the edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.vision.jit import grey, kernel, median_in_place, pairwise_sum
from doorloc.vision.sampling import (
    NO_LUT,
    Axis,
    flat_view,
    gather_profile_rows,
    gather_profiles,
    median,
    normal_cdf_pdf,
    oriented,
    pixel_buffer,
    smooth_along,
    smooth_along_rows,
    warm_up_planes,
)

__all__ = [
    "EdgeSamples",
    "FarFaceFit",
    "subpixel_edges",
    "subpixel_edges_banded",
    "subpixel_edges_far_face",
    "transition_width",
    "TextureBias",
    "texture_bias",
    "refine_step_fit",
    "block_artifact_ratio",
    "DITHERING_NOISE_LEVELS",
]

#: plateau noise (grey levels, 1-sigma) from which the noise dithers the rounding to grey levels; under it
#: the pixels of one sub-pixel phase round alike, and averaging them does not average the rounding away
#: (the response reading and the arris strip fit both ask)
DITHERING_NOISE_LEVELS = 0.5


@dataclass(frozen=True)
class EdgeSamples:
    """Edge positions found on a set of scan lines.

    Attributes
    ----------
    axis : "col" or "row"
        Profiles run along columns (``scan`` = u, ``along`` = v) or rows (``scan`` = v, ``along`` = u).
    scan : ndarray (N,) int
        Scan-line coordinate.
    along : ndarray (N,) float
        Sub-pixel edge position on the scan line, px (NaN where none).
    step : ndarray (N,) float
        Signed grey-level step ``B - A`` across the edge in the direction of increasing ``along``, 0-255 scale.
    noise : ndarray (N,) float
        Grey-level spread on the plateaus (0-255 scale), a per-sample noise figure.
    width : ndarray (N,) float
        Reserved for a per-sample transition width, px (NaN: :func:`transition_width` measures the
        width of a whole edge, which noise does not inflate).
    bright : ndarray (N,) float
        The brighter of the two plateau levels, 0-255 scale (saturation check).
    valid : ndarray (N,) bool
        Window inside the image and estimate finite.
    """

    axis: Axis
    scan: np.ndarray
    along: np.ndarray
    step: np.ndarray
    noise: np.ndarray
    width: np.ndarray
    bright: np.ndarray
    valid: np.ndarray

    def uv(self) -> np.ndarray:
        """Edge points as image ``(u, v)``, shape (N, 2)."""
        s = self.scan.astype(float)
        return np.stack([s, self.along], 1) if self.axis == "col" else np.stack([self.along, s], 1)

    def subset(self, mask: np.ndarray) -> EdgeSamples:
        return EdgeSamples(
            self.axis,
            self.scan[mask],
            self.along[mask],
            self.step[mask],
            self.noise[mask],
            self.width[mask],
            self.bright[mask],
            self.valid[mask],
        )


def _area_edges_warm_up(k) -> None:
    for buf, table in warm_up_planes(8):
        k(buf, 1, 8, 8, 8, np.arange(8), np.full(8, 1), np.ones(8, bool), 2, 1, table, 1)


@kernel(_area_edges_warm_up)
def _area_edges(
    buf, pitch_along, pitch_scan, n_along, n_scan, scan, start, finite, half, plateau, lut, level_smooth
):
    """The area estimate of :func:`subpixel_edges` with flat plateaus, compiled (:mod:`doorloc.vision.jit`).

    Profile ``i`` holds ``P[start[i] + j, scan[i]] = buf[(start[i] + j) * pitch_along + scan[i] * pitch_scan]``
    for ``j < 2 (half + plateau) + 1`` (clamped to the image), mapped by ``lut`` (float32; empty: none).
    Returns ``along`` (NaN where not valid), the two levels ``A``, ``B`` (float32 values unless smoothed along
    the edge over ``level_smooth`` scan lines each side), ``noise`` (float32) and ``valid``: the numbers of
    the numpy branch of :func:`subpixel_edges` up to the order of its float sums.
    """
    n = scan.size
    length = 2 * (half + plateau) + 1
    A = np.empty(n)
    B = np.empty(n)
    S = np.empty(n)
    noise = np.zeros(n, np.float32)
    inside = np.empty(n, np.bool_)
    row = np.empty(length, np.float32)
    for i in range(n):
        j0 = start[i]
        inside[i] = j0 >= 0 and j0 + length - 1 < n_along
        base = min(max(scan[i], 0), n_scan - 1) * pitch_scan
        for j in range(length):
            jj = min(max(j0 + j, 0), n_along - 1)
            v = buf[jj * pitch_along + base]
            row[j] = grey(lut, v)
        # the plateau levels (float32 means, as numpy's) and their spread
        a = np.float32(0.0)
        b = np.float32(0.0)
        for j in range(plateau):
            a += row[j]
            b += row[length - plateau + j]
        a = a / np.float32(plateau)
        b = b / np.float32(plateau)
        if plateau > 1:
            va = np.float32(0.0)
            vb = np.float32(0.0)
            for j in range(plateau):
                da = row[j] - a
                db = row[length - plateau + j] - b
                va += da * da
                vb += db * db
            noise[i] = np.sqrt(np.float32(0.5) * (va / np.float32(plateau) + vb / np.float32(plateau)))
        A[i] = a
        B[i] = b
        # the window's sum above the first level, in float64 (then minus the smoothed level, below)
        s = 0.0
        for j in range(plateau, plateau + 2 * half + 1):
            s += row[j]
        S[i] = s
    if level_smooth > 0:
        # each level averaged over level_smooth scan lines each side (running float32 sums, as np.cumsum
        # of the float32 levels; a profile that leaves the image takes no part)
        for X in (A, B):
            cs = np.zeros(n + 1)
            cnt = np.zeros(n + 1, np.int64)
            run = np.float32(0.0)
            for i in range(n):
                if inside[i] and np.isfinite(X[i]):
                    run += np.float32(X[i])
                    cnt[i + 1] = cnt[i] + 1
                else:
                    cnt[i + 1] = cnt[i]
                cs[i + 1] = run
            Y = np.empty(n)
            for i in range(n):
                lo = max(i - level_smooth, 0)
                hi = min(i + level_smooth + 1, n)
                Y[i] = (cs[hi] - cs[lo]) / max(cnt[hi] - cnt[lo], 1)
            X[:] = Y
    along = np.empty(n)
    valid = np.empty(n, np.bool_)
    w = 2 * half + 1
    for i in range(n):
        a = A[i]
        b = B[i] - a
        # S = (window sum - (2 half + 1) A): the area between the profile and the first level
        sa = S[i] - w * a
        den = b + np.sqrt(b * b) * np.sign(b)
        e = start[i] + plateau + 2 * half + 0.5 - 2.0 * sa / den if den != 0 else np.nan
        c0 = start[i] + half + plateau
        ok = finite[i] and inside[i] and np.isfinite(e) and abs(b) > 0 and abs(e - c0) <= half
        valid[i] = ok
        along[i] = e if ok else np.nan
    return along, A, B, noise, valid


def subpixel_edges(
    plane: np.ndarray,
    axis: Axis,
    scan: np.ndarray,
    centre: np.ndarray,
    half: int,
    plateau: int = 4,
    scale_to_8bit: float = 1.0,
    slope_smooth: int = 0,
    level_smooth: int = 0,
    lut: np.ndarray | None = None,
) -> EdgeSamples:
    """Sub-pixel edge position on each scan line by the area estimator (module docstring).

    Parameters
    ----------
    plane : ndarray (H, W)
        Luminance.
    axis : "col" or "row"
    scan : ndarray (N,) int
        Scan-line coordinates.
    centre : ndarray (N,) float
        Predicted edge position on each scan line, px; the window is centred on it.
    half : int
        The window holds ``2 half + 1`` samples around ``round(centre)``; it must hold the
        whole blurred transition.
    plateau : int
        Samples on each side beyond the window used to measure the two grey levels.
    scale_to_8bit : float
        Factor to the 0-255 scale for ``step`` and ``noise``.
    level_smooth : int
        When > 0, the two plateau levels are averaged over this many scan lines on each side (the
        samples must be ordered along the edge): the levels change slowly along an edge, so this
        takes most of the noise out of them.
    slope_smooth : int
        When > 0, each plateau's grey-level slope is measured, averaged over this many scan lines on
        each side (the samples must be ordered along the edge) and used to extrapolate the two levels
        under the transition; 0 assumes flat plateaus (exact for a linear shading only when the
        window is centred on the edge).

    Returns
    -------
    EdgeSamples
    """
    P = oriented(plane, axis)
    scan = np.asarray(scan, int)
    centre = np.asarray(centre, float)
    finite = np.isfinite(centre)
    c0 = np.round(np.where(finite, centre, 0.0)).astype(int)
    start = c0 - half - plateau
    length = 2 * (half + plateau) + 1
    flat = flat_view(P)
    if not slope_smooth > 0 and flat is not None and plane.dtype in (np.uint8, np.uint16):
        # flat plateaus (the default): compiled, one pass over each profile (_area_edges)
        buf, pitch_along, pitch_scan = flat
        along, A, B, noise, valid = _area_edges(
            buf,
            pitch_along,
            pitch_scan,
            P.shape[0],
            P.shape[1],
            scan,
            start,
            finite,
            half,
            plateau,
            lut if lut is not None else NO_LUT,
            level_smooth if scan.size else 0,
        )
        if not (level_smooth > 0 and scan.size):  # unsmoothed levels stay float32, as in the numpy branch
            A, B = A.astype(np.float32), B.astype(np.float32)
        return EdgeSamples(
            axis,
            scan,
            along,
            (B - A) * scale_to_8bit,
            noise * scale_to_8bit,
            np.full(scan.size, np.nan),
            np.maximum(A, B) * scale_to_8bit,
            valid,
        )
    vals, inside_ok = gather_profile_rows(P, scan, start, length, lut=lut)
    left = vals[:, :plateau]
    right = vals[:, -plateau:]
    core = vals[:, plateau : plateau + 2 * half + 1]
    if plateau == 1:  # the mean of one sample is the sample, its variance 0 (the same numbers, less work)
        A, B = left[:, 0], right[:, 0]
        noise = np.zeros(scan.size, vals.dtype)
    else:
        A, B = left.mean(axis=1), right.mean(axis=1)
        noise = np.sqrt(0.5 * (left.var(axis=1) + right.var(axis=1)))
    if level_smooth > 0 and scan.size:
        AB = np.stack([A, B])
        A, B = smooth_along_rows(AB if inside_ok.all() else np.where(inside_ok, AB, np.nan), level_smooth)
    step = B - A
    hp = half + 0.5
    if slope_smooth > 0 and plateau > 1 and scan.size:
        # Plateau slopes (shading, wood grain parallel to the edge), smoothed along the edge: the levels
        # are extrapolated linearly under the transition instead of being assumed flat.
        kp = np.arange(plateau) - (plateau - 1) / 2.0
        den = float((kp * kp).sum())
        a1 = ((left - A[:, None]) * kp).sum(axis=1) / den
        b1 = ((right - B[:, None]) * kp).sum(axis=1) / den
        if slope_smooth >= scan.size:  # one slope per side for the whole edge (smooth shading)
            a1 = np.full(scan.size, np.nanmedian(a1))
            b1 = np.full(scan.size, np.nanmedian(b1))
        else:
            a1, b1 = smooth_along_rows(np.stack([a1, b1]), slope_smooth)
        off = hp + (plateau + 1) / 2.0 - 0.5  # window centre to plateau centres, px
        kc = np.arange(-half, half + 1, dtype=np.float32)
        S = (core - (A[:, None] + a1[:, None] * (kc[None, :] + off))).sum(axis=1)
        D0 = (B - b1 * off) - (A + a1 * off)
        d1 = b1 - a1
        with np.errstate(divide="ignore", invalid="ignore"):
            # S = (D0 + d1 (hp - L/2)) L  for L = far window end minus edge (see the module docstring).
            b = D0 + d1 * hp
            L = 2.0 * S / (b + np.sqrt(np.maximum(b * b - 2.0 * d1 * S, 0.0)) * np.sign(b))
    else:
        # Flat plateaus (no slope): the same sums with the slope terms (zeros) left out, in float64.
        A64, B64 = A.astype(np.float64, copy=False), B.astype(np.float64, copy=False)
        S = (core - A64[:, None]).sum(axis=1)
        b = B64 - A64
        with np.errstate(divide="ignore", invalid="ignore"):
            L = 2.0 * S / (b + np.sqrt(b * b) * np.sign(b))
    along = start + plateau + 2 * half + 0.5 - L
    width = np.full(scan.size, np.nan)  # per-sample widths are too noisy to use; see transition_width
    valid = finite & inside_ok & np.isfinite(along) & (np.abs(step) > 0)
    # The estimate must lie inside its window; otherwise the transition was not captured.
    valid &= np.abs(along - c0) <= half
    return EdgeSamples(
        axis,
        scan,
        np.where(valid, along, np.nan),
        step * scale_to_8bit,
        noise * scale_to_8bit,
        width,
        np.maximum(A, B) * scale_to_8bit,
        valid,
    )


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


def subpixel_edges_banded(
    plane: np.ndarray,
    axis: Axis,
    scan: np.ndarray,
    centre: np.ndarray,
    half: int,
    band_px: np.ndarray,
    door_side: int,
    plateau: int = 4,
    scale_to_8bit: float = 1.0,
    level_smooth: int = 0,
    sharp: bool = False,
    band_slope: float = 0.0,
    lut: np.ndarray | None = None,
) -> tuple[EdgeSamples, float]:
    """Outer edge of a step with a band of unknown, uniform grey level on its door side (a chamfered or
    rounded arris seen as a strip between the background and the hinge face).

    The profile is ``background A | band L, width w | face B``. With the band width ``w`` known from
    the geometry (arris size projected), the area over the window is ``(L - A) w + (B - A)(K - e - w)``,
    ``K`` the window's door-side end; ``L`` is measured as the median grey level at the band's centre
    over the whole edge. Then ``e = K - w - (S - (L - A) w) / (B - A)``.

    Parameters
    ----------
    band_px : ndarray (N,)
        Band width on each scan line, px (>= 0).
    door_side : +1 or -1
        +1 when the door (band, then face) lies at increasing ``along``.
    sharp : bool
        The image has no optical blur (pixels are pure area samples). A band narrower than 3 px may have no
        pixel wholly inside it; its level is then found as the one whose pixel-area model of the mixed
        pixels fits best (instead of being assumed mid-grey).
    band_slope : float
        How the band width changes when the edge moves by 1 px towards the door side (0 for an arris
        strip; ``-(1 - k)`` for the far face's band, whose outer edge moves only ``k`` times as far).
        The area equation is solved with ``w = band_px + band_slope (e - centre)``.

    Returns
    -------
    samples : EdgeSamples
        As :func:`subpixel_edges`; ``step`` is ``B - A`` signed along ``along``.
    band_level : float
        The band's grey level ``L`` (0-255 scale), NaN if it could not be measured.
    """
    P = oriented(plane, axis)
    scan = np.asarray(scan, int)
    centre = np.asarray(centre, float)
    w = np.maximum(np.asarray(band_px, float), 0.0)
    finite = np.isfinite(centre) & np.isfinite(w)
    n_extra = int(math.ceil(np.nanmax(w))) if np.any(finite) else 0
    c0 = np.round(np.where(finite, centre, 0.0)).astype(int)
    length = 2 * (half + plateau) + 1 + n_extra
    if door_side > 0:
        start = c0 - half - plateau
        vals, inside = gather_profiles(P, scan, start, length, lut=lut)
    else:  # mirror so that the door side is at increasing index
        start = c0 + half + plateau
        vals, inside = gather_profiles(P, scan, start - length + 1, length, lut=lut)
        vals, inside = vals[:, ::-1], inside[:, ::-1]
    left = vals[:, :plateau]
    right = vals[:, -plateau:]
    core = vals[:, plateau : length - plateau]
    A = left.mean(axis=1)
    B = right.mean(axis=1)
    if level_smooth > 0 and scan.size:
        ok_in = inside.all(axis=1)
        A = smooth_along(np.where(ok_in, A, np.nan), level_smooth)
        B = smooth_along(np.where(ok_in, B, np.nan), level_smooth)
    # Band level: the grey value at the band's centre (linear interpolation), median over the edge,
    # from the scan lines where the band is at least 2 px wide (a pixel wholly inside it).
    rel_e = (centre - c0) * door_side  # predicted edge relative to c0, in mirrored coordinates
    pos = plateau + half + rel_e + w / 2.0  # index into vals
    i0 = np.clip(np.floor(pos).astype(int), 0, length - 2)
    fr = pos - i0
    mid = vals[np.arange(len(scan)), i0] * (1 - fr) + vals[np.arange(len(scan)), i0 + 1] * fr
    # A whole pixel inside the band; a band whose width follows the edge (far face) needs more room,
    # as its predicted position may still be off.
    wide = finite & (w >= (3.0 if band_slope else 2.0)) & inside.all(axis=1)
    L = float(np.median(mid[wide])) if np.any(wide) else float("nan")
    S = (core - A[:, None]).sum(axis=1)
    good = finite & inside.all(axis=1)
    if not np.isfinite(L) and sharp and np.any(good & (w > 0.2)):  # too narrow to hold a whole pixel
        L = _band_level_from_pixels(vals[good], A[good], B[good], S[good], w[good], plateau, half)
    with np.errstate(divide="ignore", invalid="ignore"):
        # distance from the door-side end of the window back to the outer edge; a band too narrow to
        # measure anywhere is taken at mid-grey between the two sides (error at most half its width)
        rho = 1.0 - ((L - A) / (B - A) if np.isfinite(L) else 0.5)  # 1 - band level, relative
        K = (
            core.shape[1] - 0.5
        )  # door-side end of the window, core index units (core starts at mirrored c0 - half)
        e_pred = half + rel_e
        # K - e = w rho + S / D with w = w_pred + slope (e - e_pred), solved for e. A band much brighter
        # than the face makes this ill-conditioned (the area hardly changes as the edge moves): then
        # nothing is returned (all samples invalid) and the caller measures the plain step instead.
        conditioned = 1.0 + band_slope * np.nanmedian(rho) >= 0.5
        e_mirror = (K - (w - band_slope * e_pred) * rho - S / (B - A)) / (1.0 + band_slope * rho)
        along = np.where(door_side > 0, c0 - half + e_mirror, c0 + half - e_mirror)
    step = (B - A) * door_side
    noise = np.sqrt(0.5 * (left.var(axis=1) + right.var(axis=1)))
    valid = finite & inside.all(axis=1) & np.isfinite(along) & (np.abs(B - A) > 0) & conditioned
    valid &= np.abs(along - centre) <= half
    nan = np.full(len(scan), np.nan)
    return (
        EdgeSamples(
            axis,
            scan,
            np.where(valid, along, np.nan),
            step * scale_to_8bit,
            noise * scale_to_8bit,
            nan,
            np.maximum(np.maximum(A, B), L if np.isfinite(L) else 0) * scale_to_8bit,
            valid,
        ),
        L * scale_to_8bit,
    )


def _band_level_from_pixels(vals, A, B, S, w, plateau: int, half: int, n_levels: int = 61) -> float:
    """Band level that makes the pixel-area model of a sharp ``A | L (w) | B`` profile fit best.

    For each trial level the area equation gives the edge of every profile; the trial whose modelled
    pixels (exact area coverage of the three zones) match the measured ones best wins. Mirrored
    coordinates as in :func:`subpixel_edges_banded`. Returns the level in the plane's units.
    """
    D = B - A
    lo = np.minimum(A, B).min() - 0.5 * np.abs(D).max()
    hi = np.maximum(A, B).max() + 0.5 * np.abs(D).max()
    levels = np.linspace(lo, hi, n_levels)
    n_core = vals.shape[1] - 2 * plateau
    j = np.arange(vals.shape[1], dtype=float)[None, :]
    cost = np.empty(n_levels)
    for t, lev in enumerate(levels):
        with np.errstate(divide="ignore", invalid="ignore"):
            d_end = w + (S - (lev - A) * w) / D
        e = (n_core - 0.5) - d_end + plateau  # edge in vals-index coordinates (band width as predicted)
        e = e[:, None]
        e2 = e + w[:, None]
        cov_b = np.clip(j + 0.5 - e2, 0.0, 1.0)
        cov_l = np.clip(np.minimum(j + 0.5, e2) - np.maximum(j - 0.5, e), 0.0, 1.0)
        model = A[:, None] + (lev - A)[:, None] * cov_l + D[:, None] * cov_b
        r = (vals - model)[:, plateau : plateau + n_core]
        cost[t] = np.nansum(r * r)
    k = int(np.nanargmin(cost))
    if 0 < k < n_levels - 1:  # parabolic refinement of the minimum
        c0, c1, c2 = cost[k - 1], cost[k], cost[k + 1]
        den = c0 - 2 * c1 + c2
        if den > 0:
            return float(levels[k] + 0.5 * (c0 - c2) / den * (levels[1] - levels[0]))
    return float(levels[k])


@dataclass(frozen=True)
class FarFaceFit:
    """What :func:`subpixel_edges_far_face` found besides the edge points.

    Attributes
    ----------
    band_level : float
        The far face's grey level relative to the two sides, ``(L - A) / (B - A)`` (``A`` the hinge
        face, ``B`` the background): 0 when the band looks like the hinge face, 1 like the background,
        > 1 brighter than the hinge face on a dark background... (any real value).
    blur_px : float
        Optical blur (Gaussian sigma, px) that fits the profiles best.
    band_px : float
        Median band width over the valid scan lines, px.
    arris_sigma_px : float
        Median standard error of one arris point from the profile noise, px.
    model_sigma_px : float
        How far the arris moves if the band level were off by ``LEVEL_DOUBT`` or the blur by
        ``BLUR_DOUBT`` px (the two combined as independent errors; a blur that is off also pulls the fitted
        levels, whose move counts with it): the doubt the model leaves, which noise averaging does not
        reduce. Large where a narrow band cannot be told from the arris. With an arris strip, also by the
        strip level's doubt (its fitted standard error and ``LEVEL_DOUBT``).
    strip_level : float
        The arris strip's relative level ``(S - A) / (B - A)`` (NaN without a strip).
    other_reading_px : float
        Where the band's other reading puts the arris, px from this one, positive away from the hinge face
        (a thicker door); 0 where the band's level tells the two readings apart. A band about as bright as
        the background (level near 1) leaves one step, the arris; a band about as bright as the hinge face
        (near 0) leaves one step too, the far face's back edge: the same profile, read as a door a band
        thinner or thicker (see :data:`BAND_SIDE_LEVEL`).
    """

    band_level: float
    blur_px: float
    band_px: float
    arris_sigma_px: float
    model_sigma_px: float
    strip_level: float = float("nan")
    other_reading_px: float = 0.0


#: plausible model errors of the far-face fit: band level (relative) and optical blur (px)
LEVEL_DOUBT = 0.1
BLUR_DOUBT = 0.15
#: weight of the pull of the far face's relative level towards 0.5, as a fraction of its raw information
LEVEL_PRIOR_WEIGHT = 0.02
#: a band whose fitted level lies within this of the hinge face's (0) or the background's (1), and which is at
#: least BAND_SIDE_MIN_PX wide, has another reading (:attr:`FarFaceFit.other_reading_px`): a far face as bright
#: as the hinge face beside a dark background and one as dark as the background differ only by that
#: level's few grey levels at the place the other reading puts the arris, which wood grain hides (grain set
#: seed 11, image 40: a 31 mm door under ambient light alone, its far face 3 grey levels below the hinge
#: face under 5 % grain, was measured 0.80 mm thick at a sigma of 0.034 mm). A fit of both readings on
#: profiles long enough for both was tried: the hinge face's level, read farther in, moved with the grain
#: and made the other reading's misfit decide (49 scan lines' worth on that door) where the data cannot.
BAND_SIDE_LEVEL = 0.2
BAND_SIDE_MIN_PX = 0.25


#: beyond this many blur sigmas from an edge a blurred step is 0 or 1 to within 1e-23 (Phi(-10) = 7.6e-24),
#: far below the rounding of the grey levels it is added to: :func:`_pixel_step` takes the exact limits there
STEP_TAIL_SIGMAS = 10.0


def _step_pixel_values_warm_up(k) -> None:
    k(np.arange(7.0) - 3.5, np.array([0.2, -0.4]), 0.1, STEP_TAIL_SIGMAS)
    k(np.arange(7.0) - 3.5, np.array([0.2, np.nan]), 2.0, STEP_TAIL_SIGMAS)


@kernel(_step_pixel_values_warm_up)
def _step_pixel_values(bounds, e, sigma, tail_sigmas):
    """The pixel values ``C``, ``-dC/de`` and ``dC/dsigma`` (N, M) of :func:`_pixel_step`, and whether the
    Gaussian terms were evaluated near the edges only (within ``tail_sigmas`` blur sigmas).

    Near each edge: ``Phi(y / sigma)``, ``phi(y / sigma)`` and the integral of ``Phi`` over ``y``,
    ``y Phi + sigma phi``, on a window of ``K`` boundaries per row (from the first within the tail cut,
    moved left at the far end; ``K`` the widest row's count plus one); everywhere where ``2 K`` reaches the
    boundary count or an edge is not finite.
    """
    N, n_b = e.size, bounds.size
    cut = tail_sigmas * sigma
    lo = np.searchsorted(bounds, e - cut, side="left")
    hi = np.searchsorted(bounds, e + cut, side="right")
    K = 1
    finite = True
    for i in range(N):
        K = max(K, hi[i] - lo[i] + 1)
        finite = finite and np.isfinite(e[i])
    windowed = 2 * K < n_b and finite
    C = np.empty((N, n_b - 1))
    g = np.empty((N, n_b - 1))
    h = np.empty((N, n_b - 1))
    inv = 1.0 / sigma
    G = np.empty(n_b)
    P = np.empty(n_b)
    p = np.empty(n_b)
    for i in range(N):
        j0, j1 = (min(lo[i], n_b - K), min(lo[i], n_b - K) + K) if windowed else (0, n_b)
        for j in range(n_b):
            y = bounds[j] - e[i]
            if j0 <= j < j1:
                P[j], p[j] = normal_cdf_pdf(y * inv)
                G[j] = y * P[j] + sigma * p[j]
            else:
                P[j] = 1.0 if y > 0.0 else 0.0
                p[j] = 0.0
                G[j] = max(y, 0.0)
        for j in range(n_b - 1):
            C[i, j] = G[j + 1] - G[j]
            g[i, j] = P[j + 1] - P[j]
            h[i, j] = p[j + 1] - p[j]
    return C, g, h, windowed


#: the far face's start search ranks its shifts on every START_SUBSET_EVERY-th scan line or fewer (about
#: START_SUBSET_LINES of them), where it has at least START_SUBSET_MIN_LINES, and costs the
#: START_SUBSET_KEEP best on all of them
START_SUBSET_EVERY = 4
START_SUBSET_LINES = 48
START_SUBSET_MIN_LINES = 40
START_SUBSET_KEEP = 4


@kernel(inline=True)
def _unit_step_boundaries(bounds, x, sigma, cut, G, P, p, slopes):
    """A unit step at ``x`` blurred by a Gaussian ``sigma``, on each pixel boundary (M + 1,): the
    integral of its CDF ``G`` and, with ``slopes``, the CDF ``P`` and the density ``p`` per unit
    ``y / sigma``, as :func:`_step_pixel_values` forms them; the Gaussian terms on the boundaries within
    ``cut`` of ``x`` only, the exact limits elsewhere (every boundary for an
    ``x`` not finite). A row's pixel values are the differences of neighbouring boundaries'
    (``C = G[j+1] - G[j]``, ...)."""
    n_b = bounds.size
    j0, j1 = 0, n_b
    if math.isfinite(x):
        while j0 < n_b and bounds[j0] < x - cut:
            j0 += 1
        j1 = j0
        while j1 < n_b and bounds[j1] <= x + cut:
            j1 += 1
    for j in range(j0):
        G[j] = 0.0
    for j in range(j1, n_b):
        G[j] = bounds[j] - x
    if slopes:
        for j in range(j0):
            P[j] = 0.0
            p[j] = 0.0
        for j in range(j1, n_b):
            P[j] = 1.0
            p[j] = 0.0
    inv = 1.0 / sigma
    for j in range(j0, j1):
        y = bounds[j] - x
        Pj, pj = normal_cdf_pdf(y * inv)
        G[j] = y * Pj + sigma * pj
        if slopes:
            P[j] = Pj
            p[j] = pj


@kernel(inline=True)
def _far_face_row(bounds, e, w0, e0, band_slope, strip, has_strip, sigma, cut, S, slopes):
    """One scan line's far-face steps at the arris ``e``: the arris, the band's back edge (its width ``w0``
    predicted at ``e0``, changing by ``band_slope`` per px, clipped at 0) and, with ``has_strip``, a strip's
    inner border at ``e - strip``, each on the pixel boundaries (:func:`_unit_step_boundaries`) into the
    rows of ``S`` (9, M + 1): ``G, P, p`` of the arris, then the back edge's, then the strip's. Returns
    whether a band is in view."""
    w_raw = w0 + band_slope * (e - e0)
    has_band = w_raw > 0
    _unit_step_boundaries(bounds, e, sigma, cut, S[0], S[1], S[2], slopes)
    if has_band:
        _unit_step_boundaries(bounds, e + w_raw, sigma, cut, S[3], S[4], S[5], slopes)
    else:  # the back edge at the arris (step_blur's plain steps: no band anywhere)
        S[3:6] = S[0:3]
    if has_strip:
        _unit_step_boundaries(bounds, e - strip, sigma, cut, S[6], S[7], S[8], slopes)
    return has_band


def _far_face_warm_up(k, *extra) -> None:
    core, v, bounds = np.full((3, 4), 0.5), np.ones(3), np.arange(5.0) - 0.5
    for strip in (False, True):
        k(core, v, v, bounds, v, v, v, -0.1, 0.1, STEP_TAIL_SIGMAS, v, strip, *extra)


def _far_face_start_costs_warm_up(k) -> None:
    core, v, bounds, shifts = np.full((3, 4), 0.5), np.ones(3), np.arange(5.0) - 0.5, np.array([-0.5, 0.5])
    for strip in (False, True):
        k(core, v, v, bounds, v, v, -0.1, 0.1, STEP_TAIL_SIGMAS, v, strip, 0.1, LEVEL_PRIOR_WEIGHT, shifts, 2)


@kernel(_far_face_start_costs_warm_up, reassociate=True)
def _far_face_start_costs(
    core, A, D, bounds, e0, w0, band_slope, sigma, tail, strip, has_strip, mu0, level_weight, shifts, every
):
    """The far-face fit's cost at each common shift of the arrises ``e0 + shift``, the band level solved
    (the model is linear in it) with its pull towards 0.5 included, and that level; on every ``every``-th
    profile only (a ranking of the shifts) or all (``every`` 1). A strip, if any, at its prior level
    ``mu0``."""
    n, n_m = core.shape
    rows = np.arange(0, n, every)
    J = np.empty((rows.size, n_m))
    r0 = np.empty((rows.size, n_m))
    S = np.empty((9, n_m + 1))
    cut = tail * sigma
    costs = np.empty(shifts.size)
    lams = np.empty(shifts.size)
    for s in range(shifts.size):
        info = 0.0
        jr = 0.0
        for k in range(rows.size):
            i = rows[k]
            _far_face_row(
                bounds, e0[i] + shifts[s], w0[i], e0[i], band_slope, strip[i], has_strip, sigma, cut, S, False
            )
            for j in range(n_m):
                C1 = S[0, j + 1] - S[0, j]
                C2 = S[3, j + 1] - S[3, j]
                Jl = D[i] * (C1 - C2)
                if has_strip:
                    C2 = C2 + mu0 * ((S[6, j + 1] - S[6, j]) - C1)
                r = core[i, j] - (A[i] + D[i] * C2)  # the model at band level 0
                J[k, j] = Jl
                r0[k, j] = r
                info += Jl * Jl
                jr += Jl * r
        pull = level_weight * info
        lam = (jr + pull * 0.5) / max(info + pull, 1e-12)
        cost = 0.0
        for k in range(rows.size):
            for j in range(n_m):
                r = r0[k, j] - J[k, j] * lam
                cost += r * r
        costs[s] = cost + pull * (lam - 0.5) ** 2
        lams[s] = lam
    return costs, lams


@kernel(lambda k: _far_face_warm_up(k, 0.5, 0.1), reassociate=True)
def _far_face_misfit(core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu):
    """The far-face model's sum of squared residuals over the profiles' cores, and the sum of squares of
    its derivative by the band level (the level's pull is that times LEVEL_PRIOR_WEIGHT): the model
    ``A + lam D C1 + (1 - lam) D C2`` (+ ``mu D (C0 - C1)`` with a strip), ``C1``, ``C2``, ``C0`` the
    arrises', back edges' and strip borders' pixel values (:func:`_far_face_row`)."""
    n, n_m = core.shape
    S = np.empty((9, n_m + 1))
    cut = tail * sigma
    acc = 0.0
    info = 0.0
    for i in range(n):
        _far_face_row(bounds, e[i], w0[i], e0[i], band_slope, strip[i], has_strip, sigma, cut, S, False)
        a1 = lam * D[i]
        a2 = (1.0 - lam) * D[i]
        for j in range(n_m):
            C1 = S[0, j + 1] - S[0, j]
            C2 = S[3, j + 1] - S[3, j]
            m = A[i] + a1 * C1 + a2 * C2
            if has_strip:
                m = m + mu * (D[i] * ((S[6, j + 1] - S[6, j]) - C1))
            r = core[i, j] - m
            acc += r * r
            Jl = D[i] * (C1 - C2)
            info += Jl * Jl
    return acc, info


def _far_face_sums_warm_up(k) -> None:
    for blur in (False, True):
        _far_face_warm_up(k, 0.5, 0.1, blur)


@kernel(_far_face_sums_warm_up, reassociate=True)
def _far_face_sums(
    core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, with_blur
):
    """The far-face Gauss-Newton step's sums at the arrises ``e`` (the model of :func:`_far_face_misfit`):
    per profile ``h_ee`` (the arris derivative's squares, at least 1e-12), ``h_eg`` (its products with the
    shared unknowns' derivatives: band level, blur, strip level), ``b_e`` (with the residuals) and ``rr``
    (the residuals' squares); ``H`` and ``b_g``, the shared unknowns' products among themselves and with
    the residuals. Columns of an unknown not fitted (the blur without ``with_blur``, the strip level
    without ``has_strip``) are 0.

    The steps' pixel values and slopes are formed per scan line (:func:`_far_face_row`), never as (N, M)
    arrays (allocating and filling nine of those per evaluation was most of the fit's time).
    """
    n, n_m = core.shape
    n_sh = 3 if has_strip else 2
    S = np.empty((9, n_m + 1))
    cut = tail * sigma
    h_ee = np.empty(n)
    h_eg = np.zeros((n, n_sh))
    b_e = np.empty(n)
    rr = np.empty(n)
    H = np.zeros((n_sh, n_sh))
    b_g = np.zeros(n_sh)
    Jg = np.zeros(3)
    for i in range(n):
        has_band = _far_face_row(
            bounds, e[i], w0[i], e0[i], band_slope, strip[i], has_strip, sigma, cut, S, True
        )
        a1m = lam * D[i]  # the model's
        a2 = (1.0 - lam) * D[i]
        a1 = (lam - mu) * D[i]  # the arris derivative's (a strip's level takes its share)
        fb = 1.0 + band_slope * has_band
        muD = mu * D[i]
        ee = 0.0
        er = 0.0
        sr = 0.0
        eg0 = eg1 = eg2 = 0.0
        for j in range(n_m):
            C1 = S[0, j + 1] - S[0, j]
            C2 = S[3, j + 1] - S[3, j]
            m = A[i] + a1m * C1 + a2 * C2
            Je = -a1 * (S[1, j + 1] - S[1, j]) - a2 * (S[4, j + 1] - S[4, j]) * fb
            Jg[0] = D[i] * (C1 - C2)
            if with_blur:
                Jg[1] = a1 * (S[2, j + 1] - S[2, j]) + a2 * (S[5, j + 1] - S[5, j])
            if has_strip:
                Jg[2] = D[i] * ((S[6, j + 1] - S[6, j]) - C1)
                m = m + mu * Jg[2]
                Je = Je - muD * (S[7, j + 1] - S[7, j])
                if with_blur:
                    Jg[1] = Jg[1] + muD * (S[8, j + 1] - S[8, j])
            r = core[i, j] - m
            ee += Je * Je
            er += Je * r
            sr += r * r
            eg0 += Je * Jg[0]
            eg1 += Je * Jg[1]
            eg2 += Je * Jg[2]
            for k in range(n_sh):
                b_g[k] += Jg[k] * r
                for q in range(k + 1):
                    H[k, q] += Jg[k] * Jg[q]
        h_ee[i] = max(ee, 1e-12)
        b_e[i] = er
        rr[i] = sr
        h_eg[i, 0] = eg0
        h_eg[i, 1] = eg1
        if has_strip:
            h_eg[i, 2] = eg2
    for k in range(n_sh):
        for q in range(k):
            H[q, k] = H[k, q]
    return h_ee, h_eg, b_e, H, b_g, rr


@kernel(inline=True)
def _clip(x, lo, hi):
    """``np.clip`` of a number (NaN stays NaN)."""
    return lo if x < lo else (hi if x > hi else x)


@kernel(inline=True)
def _py_max(a, b):
    """Python's ``max(a, b)`` of two numbers (``a`` unless ``b`` is larger: a NaN ``a`` stays)."""
    return b if b > a else a


@kernel(inline=True)
def _py_min(a, b):
    """Python's ``min(a, b)`` of two numbers (``a`` unless ``b`` is smaller)."""
    return b if b < a else a


def _far_face_schur_warm_up(k) -> None:
    for n_sh in (2, 3):
        k(np.eye(n_sh), np.ones(n_sh), np.ones(3), np.ones((3, n_sh)), np.ones(3), 0.5, 0.1, 0.02, 1.0, 0.2)


@kernel(_far_face_schur_warm_up)
def _far_face_schur(H, b_g, h_ee, h_eg, b_e, lam, mu, level_weight, pull_mu, mu0):
    """The far-face normal equations of the shared unknowns (band level, blur and, with a third column, a
    strip's level) with the arrises eliminated (Schur complement), in place in ``H`` and ``b_g``, from
    :func:`_far_face_sums`.

    With the level's pull towards mid-grey (``level_weight`` times its information) and, with a strip,
    the strip level's pull ``pull_mu`` towards its prior ``mu0``; a small ridge keeps a level that no
    scan line sees (a band nowhere in view) from leaving the system singular."""
    n, n_sh = h_eg.shape
    level_info = H[0, 0]  # sum of J_lam ** 2
    for k in range(n_sh):
        for q in range(n_sh):
            acc = 0.0
            for i in range(n):
                acc += h_eg[i, k] / h_ee[i] * h_eg[i, q]
            H[k, q] -= acc
        acc = 0.0
        for i in range(n):
            acc += h_eg[i, k] * (b_e[i] / h_ee[i])
        b_g[k] -= acc
    for k in range(n_sh):
        H[k, k] += max(H[k, k], 1e-12) * 1e-6 + 1e-9
    # Where the band is much narrower than the blur, its level and the arrises trade off (the Schur
    # complement keeps little of the level's information): a weak pull towards mid-grey between the two
    # sides then settles the level, as little as the data allow.
    prior = level_weight * level_info
    H[0, 0] += prior
    b_g[0] += prior * (0.5 - lam)
    if n_sh == 3:  # the strip's level: its prior (a strip narrower than the blur trades it with e)
        H[2, 2] += pull_mu
        b_g[2] += pull_mu * (mu0 - mu)


def _far_face_gauss_newton_warm_up(k) -> None:
    core, v, bounds = np.full((3, 4), 0.5), np.ones(3), np.arange(5.0) - 0.5
    for strip in (False, True):
        for blur in (False, True):
            k(core, v, v, bounds, v.copy(), v, v, -0.1, 0.5, STEP_TAIL_SIGMAS, v, strip, 0.5, 0.1, blur, 2,
              LEVEL_PRIOR_WEIGHT, 1.0, 0.1, -1.0, 2.0)  # fmt: skip


@kernel(_far_face_gauss_newton_warm_up)
def _far_face_gauss_newton(
    core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, fit_blur, n_iter,
    level_weight, pull_mu, mu0, levels_lo, levels_hi,
):  # fmt: skip
    """:func:`subpixel_edges_far_face`'s Gauss-Newton iterations from the arrises ``e`` (N,), band level
    ``lam``, blur ``sigma`` and strip level ``mu``: each step moves every arris and the shared unknowns
    together (one unknown per scan line plus the shared ones, solved through the Schur complement: the
    arrises and the level are strongly coupled where the band is narrow), and is taken whole or halved
    up to three times, only where it lowers the cost (the band's width is clipped at zero, a kink a full
    step can jump across into the false minimum where the band has vanished). Returns the final
    ``e, lam, sigma, mu`` and cost (misfit and pulls). Compiled: as Python, ~20 numpy calls a step."""
    e = e.copy()
    n = e.size

    def cost_at(e, lam, sigma, mu):
        misfit, info = _far_face_misfit(
            core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu
        )
        c = misfit + level_weight * info * (lam - 0.5) ** 2
        return c + pull_mu * (mu - mu0) ** 2 if has_strip else c

    cost = cost_at(e, lam, sigma, mu)
    de = np.empty(n)
    trial = np.empty(n)
    for _ in range(n_iter):
        h_ee, h_eg, b_e, H, b_g, _rr = _far_face_sums(
            core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, fit_blur
        )
        _far_face_schur(H, b_g, h_ee, h_eg, b_e, lam, mu, level_weight, pull_mu, mu0)
        d = np.linalg.solve(H, b_g)
        d_lam, d_sig = _clip(d[0], -1.0, 1.0), _clip(d[1], -0.5, 0.5)
        d_mu = _clip(d[2], -1.0, 1.0) if has_strip else 0.0
        for i in range(n):
            acc = h_eg[i, 0] * d_lam + h_eg[i, 1] * d_sig
            if has_strip:
                acc += h_eg[i, 2] * d_mu
            de[i] = _clip((b_e[i] - acc) / h_ee[i], -1.0, 1.0)
        accepted = False
        step = 1.0
        t_lam, t_sig, t_mu, c = lam, sigma, mu, cost
        for _h in range(4):
            for i in range(n):
                trial[i] = e[i] + step * de[i]
            t_lam = lam + step * d_lam
            t_sig = _clip(sigma + step * d_sig, 0.05, 5.0)
            t_mu = mu + step * d_mu
            if has_strip:
                t_lam = _py_min(_py_max(t_lam, levels_lo), levels_hi)
                t_mu = _py_min(_py_max(t_mu, levels_lo), levels_hi)
            c = cost_at(trial, t_lam, t_sig, t_mu)
            if c <= cost:
                accepted = True
                break
            step *= 0.5
        if not accepted:
            break
        big = 0.0  # np.max(np.abs(step * de)), NaN as numpy's
        for i in range(n):
            v = abs(step * de[i])
            if v > big or v != v:
                big = v
        e, trial = trial, e
        lam, sigma, mu = t_lam, t_sig, t_mu
        done = cost - c <= 1e-9 * _py_max(cost, 1e-12) or (
            big < 1e-4 and abs(step * d_lam) < 1e-4 and abs(step * d_mu) < 1e-4
        )
        cost = c
        if done:
            break
    return e, lam, sigma, mu, cost


def _levels_per_blur(
    H: np.ndarray,
    b_g: np.ndarray,
    h_ee: np.ndarray,
    h_eg: np.ndarray,
    b_e: np.ndarray,
    lam: float,
    mu: float,
    pull_mu: float,
    mu0: float,
    has_strip: bool,
) -> tuple[float, float]:
    """How far the far-face fit's band level (and a strip's level) move per px of error in the blur it was
    given, the arrises refitted along: from the step's sums at the answer (:func:`_far_face_sums` with the
    blur's column, not changed here) through the Schur complement the fit solves, pulls included. Each at
    most ``1 / BLUR_DOUBT`` (a blur off by its doubt moves a level by at most its whole range, hinge face to
    background; the linear reading does not hold beyond it).

    Why: beside a band about as narrow as the blur the level and the blur trade off, and the fit's level
    follows whatever blur it was given. Counted as the blur's doubt at a fixed level, the arris's doubt
    missed that: a 1 px band beside a 1.4 px blur, its level read 0.55 for a far face about as bright as the
    hinge face, put the thickness 0.26 mm off at 7 sigma (bench_surfaces --seed 9100, hard_007; a blur off
    by 0.15 px moves that level by 0.55); with the level's pull counted, 2.5 sigma.
    """
    Hs, bs = H.copy(), b_g.copy()
    _far_face_schur(Hs, bs, h_ee, h_eg, b_e, lam, mu, LEVEL_PRIOR_WEIGHT, pull_mu, mu0)
    # the levels' rows of the reduced normal equations, solved for a unit blur change (one or two
    # unknowns: in closed form)
    if has_strip:
        det = Hs[0, 0] * Hs[2, 2] - Hs[0, 2] * Hs[2, 0]
        d_lam = (-Hs[0, 1] * Hs[2, 2] + Hs[0, 2] * Hs[2, 1]) / det if det != 0 else math.nan
        d_mu = (-Hs[2, 1] * Hs[0, 0] + Hs[2, 0] * Hs[0, 1]) / det if det != 0 else math.nan
    else:
        d_lam = -Hs[0, 1] / Hs[0, 0] if Hs[0, 0] != 0 else math.nan
        d_mu = 0.0
    if not (math.isfinite(d_lam) and math.isfinite(d_mu)):
        return 0.0, 0.0
    cap = 1.0 / BLUR_DOUBT
    return min(max(float(d_lam), -cap), cap), min(max(float(d_mu), -cap), cap)


def _pixel_step(bounds: np.ndarray, e: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit steps at ``e`` (N,), blurred by a Gaussian ``sigma`` and integrated over pixels (compiled:
    :func:`_step_pixel_values`).

    ``bounds`` (M + 1,) are the pixel boundaries, ascending (pixel ``i`` spans ``bounds[i]..bounds[i + 1]``).
    Returns, each (N, M), the pixel values ``C``, ``-dC/de`` (``g``) and ``dC/dsigma`` (``h``). The Gaussian
    terms (``Phi``, ``exp``: most of the cost) are evaluated only on the boundaries within
    :data:`STEP_TAIL_SIGMAS` blur sigmas of each edge; beyond them the step's exact limits (``Phi`` 0 or 1,
    ``phi`` 0, its integral 0 or ``y``) stand in, which differ from the full evaluation by less than 1e-22.
    A narrow blur (rendered and most real frames: sigma < 0.2 px) thus costs a few boundaries per scan line
    instead of the whole window.
    """
    C, g, h, _ = _step_pixel_values(
        np.ascontiguousarray(bounds, np.float64),
        np.ascontiguousarray(e, np.float64),
        float(sigma),
        STEP_TAIL_SIGMAS,
    )
    return C, g, h


def subpixel_edges_far_face(
    plane: np.ndarray,
    axis: Axis,
    scan: np.ndarray,
    centre: np.ndarray,
    half: int,
    band_px: np.ndarray,
    band_slope: float,
    outward: int,
    plateau: int = 4,
    scale_to_8bit: float = 1.0,
    blur_px: float = 1.0,
    level_smooth: int = 0,
    lut: np.ndarray | None = None,
    n_iter: int = 10,
    fit_blur: bool = False,
    strip_px: np.ndarray | None = None,
    strip_radiance: tuple[float, float] = (0.9, 0.45),
    strip_shaded: bool = False,
) -> tuple[EdgeSamples, FarFaceFit]:
    """The far arris beside a visible far face, by fitting the whole profile across it.

    Seen from a camera beyond the far face's plane, the profile across the far arris is
    ``hinge face A | far face L, width w | background B``: two steps, the arris at ``e`` and the far
    face's back edge at ``e + w``. The band width follows from the geometry,
    ``w = band_px + band_slope (e - centre)`` (the back edge lies the door's width farther away and moves
    less), so each scan line has one unknown, ``e``; the band's relative level
    ``(L - A) / (B - A)`` (the same all along the edge under any smooth shading) and the optical blur
    are shared by all scan lines. They are fitted by Gauss-Newton on the pixel values, with each pixel
    modelled as a Gaussian-blurred step integrated over the pixel.

    Unlike the area estimator this uses the shape of the profile, so a narrow band brighter than the
    hinge face (which moves the profile's centroid the wrong way as the arris moves) does not make the
    estimate ill-conditioned.

    Parameters
    ----------
    plane, axis, scan, centre, half, plateau, scale_to_8bit, level_smooth, lut
        As :func:`subpixel_edges`.
    band_px : ndarray (N,)
        Predicted band width on each scan line at the predicted edge ``centre``, px, signed: <= 0
        where no band is in view (the far face seen edge-on or from behind).
    band_slope : float
        ``dw / de`` as the arris moves outwards (``-(1 - k)``, ``k`` the back edge's relative scale).
    outward : +1 or -1
        Direction of increasing ``along`` that leads from the hinge face across the arris.
    blur_px : float
        The optical blur (Gaussian sigma), px, e.g. from :func:`step_blur` on another edge; with a band
        narrower than the blur, the band's level, its width and the blur trade off against each other,
        so the blur is best measured where the step is plain.
    fit_blur : bool
        Fit the blur too (starting at ``blur_px``); only sound where the band is much wider than the blur.
    strip_px : ndarray (N,), optional
        A chamfered or rounded far arris: the strip's width on the hinge-face side of ``e``, px (``e`` is
        then the far face's near border, where the strip meets it). The profile is ``hinge face A | strip S
        | far face L | background B``, the strip's relative level ``(S - A) / (B - A)`` one more shared
        unknown, with the prior that the strip's radiance is ``strip_radiance`` (mean, standard deviation)
        times the hinge face's (:data:`doorloc.vision.arris_model.STRIP_RADIANCE`). Without it a strip
        took the far face's level or the hinge face's and the thickness was up to the strip's width off
        with a sigma that did not know it (thin doors with 0.5-3 mm arrises: 1.2 mm at 12 sigma).
    strip_radiance : (float, float)
        The strip's radiance over the hinge face's, prior mean and standard deviation.
    strip_shaded : bool
        The strip is a rounding, whose shading runs across it from the hinge face's level towards the far
        face's: its one fitted level is in doubt by that range's spread too.

    Returns
    -------
    samples : EdgeSamples
        ``along`` = the arris; ``step`` = ``B - A`` signed along ``along``.
    fit : FarFaceFit
    """
    P = oriented(plane, axis)
    scan = np.asarray(scan, int)
    centre = np.asarray(centre, float)
    w0 = np.asarray(band_px, float)
    finite = np.isfinite(centre) & np.isfinite(w0)
    w0 = np.where(finite, w0, 0.0)
    c0 = np.round(np.where(finite, centre, 0.0)).astype(int)
    n_extra = int(math.ceil(max(float(np.max(w0, initial=0.0)), 0.0))) + 1
    ws = (
        np.zeros(len(scan))
        if strip_px is None
        else np.where(np.isfinite(strip_px), np.maximum(np.asarray(strip_px, float), 0.0), 0.0)
    )
    has_strip = bool(np.any(ws > 0))
    # the hinge face's plateau beyond the strip (and the blur beside it), and room for the border a
    # strip's width either way (the second reading of the profile, below)
    n_strip = int(math.ceil(float(ws.max(initial=0.0)) + 2.0 * blur_px)) if has_strip else 0
    length = 2 * (half + plateau) + 1 + n_extra + 2 * n_strip
    if outward > 0:
        start = c0 - half - plateau - n_strip
        vals, inside = gather_profiles(P, scan, start, length, lut=lut)
    else:  # mirror so that the hinge face is at the low indices
        start = c0 + half + plateau + n_strip
        vals, inside = gather_profiles(P, scan, start - length + 1, length, lut=lut)
        vals, inside = vals[:, ::-1], inside[:, ::-1]
    vals = vals.astype(np.float64)
    A = vals[:, :plateau].mean(axis=1)
    B = vals[:, -plateau:].mean(axis=1)
    ok = finite & inside.all(axis=1)
    if level_smooth > 0 and scan.size:
        A = smooth_along(np.where(ok, A, np.nan), level_smooth)
        B = smooth_along(np.where(ok, B, np.nan), level_smooth)
    D = B - A
    ok &= np.isfinite(D) & (np.abs(D) > 0)
    e0 = plateau + n_strip + half + (centre - c0) * outward  # predicted arris, index units
    # Only the core (between the plateaus) carries the edges; the plateaus fix A and B.
    core = vals[ok, plateau : length - plateau]
    bounds = np.arange(plateau, length - plateau + 1, dtype=np.float64) - 0.5
    Ao, Do, e0o, w0o = A[ok], D[ok], e0[ok], w0[ok]
    wso = ws[ok] if has_strip else None
    e = e0o.copy()
    sigma = float(np.clip(blur_px, 0.05, 5.0))
    n_ok = int(ok.sum())
    # The strip's relative level (S - A) / (B - A) a priori: its radiance a fraction of the hinge face's
    # (linear light), in units of the contrast; weighed at the profiles' noise.
    mu0 = mu_sd = pull_mu = 0.0
    levels_lo, levels_hi = -math.inf, math.inf
    if has_strip and n_ok:
        a_med, d_med = median(Ao), median(Do)
        k = -a_med / d_med if abs(d_med) > 1e-9 * max(abs(a_med), 1e-12) else 0.0
        mu0 = (strip_radiance[0] - 1.0) * -k
        mu_sd = max(strip_radiance[1] * abs(k), 0.05)
        # The strip's and the far face's levels where their radiance is 0-3 times the hinge face's (the
        # same wood: in shadow, or glinting). A far face seen nearly edge-on, a band of a hundredth of a
        # pixel, otherwise took a level of -32 (a spike that moves the step at no cost: effects fixture
        # img_0007, its bottom end then refused as not straight).
        levels_lo, levels_hi = sorted((k, -2.0 * k))
        ends = np.concatenate([vals[ok, :plateau], vals[ok, -plateau:]], axis=1)
        noise_var = max(median(ends.var(axis=1)), (1e-3 * abs(d_med)) ** 2)
        pull_mu = noise_var / mu_sd**2
    strip_o = wso if wso is not None else np.zeros(n_ok)  # (the kernels take a width on every line)

    lam, mu = 0.5, mu0
    if n_ok:
        # Start from the best common shift of all arrises (half-pixel steps across the window): a
        # prediction that took the band's outer edge for the arris sits in a false minimum where the
        # band has shrunk to nothing, which Gauss-Newton would not leave.
        shifts = np.arange(-half, half + 0.25, 0.5)

        def start_costs(shifts: np.ndarray, every: int) -> tuple[np.ndarray, np.ndarray]:
            # (a strip at its prior level while the start is searched)
            return _far_face_start_costs(
                core, Ao, Do, bounds, e0o, w0o, band_slope, sigma, STEP_TAIL_SIGMAS, strip_o, has_strip,
                mu0, LEVEL_PRIOR_WEIGHT, shifts, every,
            )  # fmt: skip

        if n_ok >= START_SUBSET_MIN_LINES and not has_strip:
            # The shifts' costs differ by whole bands of misfit: every START_SUBSET_EVERY-th scan line ranks
            # them, and the few best are then costed on every line (at a third of the work: the start search
            # was two thirds of the far face's time). Not a proof of the same winner, but it was on every
            # parity case, 130 random renders and the noisy cases of test_edges_lines.
            every = max(START_SUBSET_EVERY, n_ok // START_SUBSET_LINES)
            sub, _ = start_costs(shifts, every)
            shifts = shifts[np.sort(np.argsort(sub, kind="stable")[:START_SUBSET_KEEP])]
        costs, lams = start_costs(shifts, 1)
        best = (math.inf, 0.0, 0.5)
        for shift, cost, lam_s in zip(shifts.tolist(), costs.tolist(), lams.tolist(), strict=True):
            if cost < best[0]:
                best = (cost, shift, lam_s)
        e = e0o + best[1]
        lam = best[2]

    def gauss_newton(
        e: np.ndarray, lam: float, sigma: float, mu: float
    ) -> tuple[np.ndarray, float, float, float, float]:
        return _far_face_gauss_newton(
            core, Ao, Do, bounds, e, w0o, e0o, band_slope, sigma, STEP_TAIL_SIGMAS, strip_o, has_strip,
            lam, mu, fit_blur, n_iter, LEVEL_PRIOR_WEIGHT, pull_mu, mu0, levels_lo, levels_hi,
        )  # fmt: skip

    strip_doubt = 0.0
    if n_ok:
        e, lam, sigma, mu, cost = gauss_newton(e, lam, sigma, mu)
    if n_ok and has_strip:
        # A strip as bright as the far face (or as the hinge face) is also read as a door thinner (or
        # thicker) by the strip's width, its far face wider (or its strip invisible): the two explain the
        # profiles alike, and only their misfits tell them apart. Each is fitted from the other's place;
        # the better is kept, and the other weighs in as a second place for the border (its misfit excess
        # at the scale of the residuals of one scan line: a model's error is common to all of them).
        assert wso is not None
        w_med = median(wso)
        chosen: tuple[np.ndarray, float, float, float, float] = (e, lam, sigma, mu, cost)
        others = []
        for sgn in (1.0, -1.0):
            alt = gauss_newton(chosen[0] + sgn * w_med, chosen[1], chosen[2], mu0)
            if np.all(np.abs(alt[0] - e0o) <= half + n_strip):
                others.append(alt)
        if others:
            ranked = sorted([chosen, *others], key=lambda t: t[4])
            chosen = ranked[0]
            per_line = chosen[4] / max(n_ok, 1)
            for alt in ranked[1:]:
                q = math.exp(-min((alt[4] - chosen[4]) / (2.0 * max(per_line, 1e-300)), 50.0))
                shift = median(alt[0] - chosen[0])
                strip_doubt = max(strip_doubt, abs(shift) * math.sqrt(q / (1.0 + q)))
        e, lam, sigma, mu, cost = chosen
    other_reading = 0.0
    if n_ok and not has_strip and min(abs(lam), abs(1.0 - lam)) <= BAND_SIDE_LEVEL:
        w_med = median(np.maximum(w0o + band_slope * (e - e0o), 0.0))
        if w_med >= BAND_SIDE_MIN_PX:
            # The band read as the background's: the step is the arris here, and the far face's back edge in
            # the other reading, whose arris lies inwards by its band's width, w / (1 + band_slope) (the band
            # widens as the arris moves in). Read as the hinge face's: the other way, by this band's width.
            other_reading = float(-w_med / max(1.0 + band_slope, 0.1) if lam >= 0.5 else w_med)
    e_all = np.full(len(scan), np.nan)
    e_sigma = np.full(len(scan), np.nan)
    de_dlam = de_dsig = de_dmu = np.zeros(0)
    mu_doubt = 0.0
    if n_ok:
        h_ee, h_eg, b_e, H, b_g, rr = _far_face_sums(
            core, Ao, Do, bounds, e, w0o, e0o, band_slope, sigma, STEP_TAIL_SIGMAS, strip_o, has_strip,
            lam, mu, True,
        )  # fmt: skip
        res_var = rr / max(core.shape[1] - 1, 1)
        info = h_ee  # the arris derivative's squares
        e_sigma[ok] = np.sqrt(res_var / info)
        e_all[ok] = e
        # How each arris would move to keep fitting its profile if the level or the blur were off. The
        # blur is not fitted here (the reference arris's): where the band is about as narrow as the blur,
        # a blur that is off pulls the fitted level with it, and the level moves the arris too, at most by
        # the band's (and a strip's) width: the readings a level can give lie between the arris and the
        # band's back edge.
        de_dlam = -h_eg[:, 0] / info
        lam_per_blur, mu_per_blur = _levels_per_blur(
            H, b_g, h_ee, h_eg, b_e, lam, mu, pull_mu, mu0, has_strip
        )
        pulled = de_dlam * lam_per_blur
        if has_strip:
            pulled = pulled - h_eg[:, 2] / info * mu_per_blur
        reach = (np.maximum(w0o + band_slope * (e - e0o), 0.0) + strip_o) / BLUR_DOUBT
        de_dsig = -h_eg[:, 1] / info + np.clip(pulled, -reach, reach)
        if has_strip:
            de_dmu = -h_eg[:, 2] / info
            # the strip level's own doubt (shared by every scan line: the Schur complement's, at the
            # residuals' scale; the blur not among the unknowns) and that of one level standing for a
            # strip's shading (a rounding's runs across it), as the band's
            h_eg[:, 1] = b_g[1] = 0.0
            H[1, :] = H[:, 1] = 0.0
            _far_face_schur(H, b_g, h_ee, h_eg, b_e, lam, mu, LEVEL_PRIOR_WEIGHT, pull_mu, mu0)
            try:
                var_mu = float(np.linalg.inv(H)[2, 2]) * median(res_var)
            except np.linalg.LinAlgError:
                var_mu = mu_sd**2
            # (a rounding's shading runs from the hinge face's level towards the far face's across the
            # strip: one level stands for it within about a uniform spread over that range)
            spread = abs(lam) / math.sqrt(12.0) if strip_shaded else 0.0
            mu_doubt = math.hypot(math.sqrt(max(min(var_mu, mu_sd**2), 0.0)), max(LEVEL_DOUBT, spread))
    e = e_all
    along = np.where(outward > 0, start + e, start - e)
    valid = ok & np.isfinite(along) & (np.abs(e - e0) <= half + n_strip) & np.isfinite(e_sigma)
    w_fit = np.maximum(w0 + band_slope * (e - e0), 0.0)
    band_med = median(w_fit[valid]) if np.any(valid) else float("nan")
    model_sigma = (
        math.hypot(median(de_dlam) * LEVEL_DOUBT, median(de_dsig) * BLUR_DOUBT)
        if de_dlam.size
        else float("nan")
    )
    if de_dmu.size:  # the strip's level, and another place for the border that fits about as well
        model_sigma = math.hypot(model_sigma, median(de_dmu) * mu_doubt, strip_doubt)
    noise = np.sqrt(0.5 * (vals[:, :plateau].var(axis=1) + vals[:, -plateau:].var(axis=1)))
    step = D * outward
    nan = np.full(len(scan), np.nan)
    # the brightest level seen (the saturation check): the band's fitted level only as far as a pixel of
    # the profile reaches it (a level fitted beyond them, 1258 grey levels on a chamfer read with the
    # wrong camera exponent, is no pixel's, and refused a door peaking at 228 as overexposed)
    band_level = np.minimum(A + lam * D, vals.max(axis=1))
    samples = EdgeSamples(
        axis,
        scan,
        np.where(valid, along, np.nan),
        step * scale_to_8bit,
        noise * scale_to_8bit,
        nan,
        np.maximum(np.maximum(A, B), band_level) * scale_to_8bit,
        valid,
    )
    fit = FarFaceFit(
        lam,
        sigma,
        band_med,
        median(e_sigma[valid]) if np.any(valid) else float("nan"),
        model_sigma,
        float(mu) if has_strip else float("nan"),
        other_reading,
    )
    return samples, fit


def step_blur(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    plateau: int = 4,
    lut: np.ndarray | None = None,
    blur_px: float = 1.0,
    max_lines: int = 160,
) -> float:
    """Optical blur (Gaussian sigma, px, the pixel's own width not included) of a plain step edge.

    Each profile across the edge is modelled as a Gaussian-blurred step integrated over the pixels
    (the model of :func:`subpixel_edges_far_face` without a band) and the blur shared by all profiles
    is fitted with every edge position. Unlike :func:`transition_width` this is not inflated by noise
    or texture. Returns NaN when no sample is usable.
    """
    idx = np.flatnonzero(mask & samples.valid)
    if idx.size == 0:
        return float("nan")
    idx = idx[:: max(idx.size // max_lines, 1)]
    sub = samples.subset(np.isin(np.arange(samples.scan.size), idx))
    _, fit = subpixel_edges_far_face(
        plane,
        sub.axis,
        sub.scan,
        sub.along,
        half,
        np.full(sub.scan.size, -1.0),
        0.0,
        1,
        plateau,
        1.0,
        blur_px=blur_px,
        lut=lut,
        fit_blur=True,
        n_iter=15,
    )
    return fit.blur_px


def _step_fit(
    vals: np.ndarray, e: np.ndarray, bounds: np.ndarray, sigma: float, n_iter: int = 6
) -> np.ndarray:
    """Edge positions (N,) that make ``A + (B - A) C(k; e, sigma)`` fit each profile row of ``vals`` best.

    ``C`` is a Gaussian-blurred unit step integrated over each pixel (:func:`_pixel_step`), ``bounds`` the
    pixel boundaries in the coordinates of ``e``. Per row, ``A`` and ``B`` are solved linearly for the
    current edge and the edge takes a Gauss-Newton step (clipped to half a pixel) - a variable-projection
    fit with three unknowns per scan line (compiled: :func:`_step_fit_rows`).
    """
    return _step_fit_rows(
        np.ascontiguousarray(vals, np.float64),
        np.array(e, np.float64),
        np.ascontiguousarray(bounds, np.float64),
        float(sigma),
        n_iter,
    )


def _step_fit_warm_up(k) -> None:
    k(np.full((2, 6), 0.5), np.zeros(2), np.arange(7.0) - 3.5, 0.5, 2)


@kernel(_step_fit_warm_up)
def _step_fit_rows(vals, e, bounds, sigma, n_iter):
    """:func:`_step_fit`'s iterations (``e`` updated in place and returned): each row's sums in numpy's
    order (written with numpy, 7 row sums and a dozen array operations per iteration took 2-3 ms of a
    textured frame's step fits)."""
    N, M = vals.shape
    t = np.empty((7, M))
    for _ in range(n_iter):
        C, g, _, _ = _step_pixel_values(bounds, e, sigma, STEP_TAIL_SIGMAS)
        for i in range(N):
            for k in range(M):
                x0 = 1.0 - C[i, k]
                t[0, k] = x0 * x0
                t[1, k] = x0 * C[i, k]
                t[2, k] = C[i, k] * C[i, k]
                t[3, k] = x0 * vals[i, k]
                t[4, k] = C[i, k] * vals[i, k]
            s00, s01, s11 = pairwise_sum(t[0], 0, M), pairwise_sum(t[1], 0, M), pairwise_sum(t[2], 0, M)
            b0, b1 = pairwise_sum(t[3], 0, M), pairwise_sum(t[4], 0, M)
            det = s00 * s11 - s01 * s01
            A = (s11 * b0 - s01 * b1) / det
            B = (s00 * b1 - s01 * b0) / det
            for k in range(M):
                r = vals[i, k] - (A * (1.0 - C[i, k]) + B * C[i, k])
                J = (B - A) * g[i, k]  # -dm/de (g = -dC/de)
                t[5, k] = J * r
                t[6, k] = J * J
            de = -pairwise_sum(t[5], 0, M) / pairwise_sum(t[6], 0, M)
            e[i] = e[i] + (min(max(de, -0.5), 0.5) if np.isfinite(de) else 0.0)
    return e


def refine_step_fit(
    plane: np.ndarray, samples: EdgeSamples, half: int, blur_px: float, lut: np.ndarray | None = None
) -> EdgeSamples:
    """Refine area-estimator edge points by fitting a blurred step with free levels on each scan line.

    The area estimator takes the two grey levels from plateaus beyond its window and assumes they hold
    under the transition; texture along the edge (wood grain) breaks that by the difference between the
    texture under the window and at the plateaus. Fitting ``A + (B - A) C(k; e, blur)`` to the window itself
    (``half + 1`` px each side, ``A`` and ``B`` free per scan line) takes both levels from right beside
    the transition instead, and weighs the pixels by how much they say about the edge (the steep part):
    on the bench's wood-grain set it halves the area estimator's error, and on clean steps it is
    as exact. ``blur_px`` (Gaussian sigma, px, without the pixel) only shapes the model: a symmetric
    misfit of it does not move a symmetric edge. Points that the fit moves by more than a pixel, or not
    to a finite value, keep the area estimate.
    """
    ok = samples.valid & np.isfinite(samples.along)
    if not np.any(ok) or not np.isfinite(blur_px):
        return samples
    P = oriented(plane, samples.axis)
    a0 = samples.along[ok]
    c0 = np.round(a0).astype(int)
    h = half + 1
    vals, inside = gather_profiles(P, samples.scan[ok], c0 - h, 2 * h + 1, lut=lut)
    bounds = np.arange(-h, h + 2, dtype=np.float64) - 0.5
    e = _step_fit(vals, a0 - c0, bounds, max(float(blur_px), 0.05))
    fitted = c0 + e
    keep = inside.all(axis=1) & np.isfinite(fitted) & (np.abs(fitted - a0) <= 1.0)
    along = samples.along.copy()
    along[np.flatnonzero(ok)[keep]] = fitted[keep]
    return EdgeSamples(
        samples.axis,
        samples.scan,
        along,
        samples.step,
        samples.noise,
        samples.width,
        samples.bright,
        samples.valid,
    )


@dataclass(frozen=True)
class TextureBias:
    """How much the texture beside an edge can move the area estimator, measured beside the window.

    Attributes
    ----------
    offset_sigma_px : float
        1-sigma of the bias the surface texture next to the edge gives the line's offset, px (across
        the edge): the RMS of the area estimator's error on the texture just beyond its window.
    tilt_sigma : float
        1-sigma of the bias in the line's direction (px of offset per px along the edge), from how that
        error differs between the two halves of the edge (grain that wanders along the edge).
    """

    offset_sigma_px: float
    tilt_sigma: float


def texture_bias(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    plateau: int,
    lut: np.ndarray | None = None,
    n_shifts: int = 12,
    max_lines: int = 128,
    blur_px: float | None = None,
    door_skip_px: int = 0,
    door_side: int = 1,
) -> TextureBias:
    """Estimate the texture bias of the sub-pixel edge estimate on one edge from the texture beside its window.

    The estimators take the edge's two grey levels from near the transition and assume they hold under it;
    surface texture (wood grain along the edge) breaks that. The texture under the transition cannot be
    told from the step, but texture that runs along the edge is the same on every scan line at the same
    distance from it, so its mean profile beside the window is measured with little noise (the mean over
    the scan lines that the line fit kept, aligned on their edge points). Taking the texture as stationary across the edge, the
    estimator is run on that texture as if it lay under the window, at ``n_shifts`` positions beyond it on
    each side; the RMS of the edge shifts it makes is the 1-sigma. A plain or smoothly shaded surface
    gives ~0 (noise only).

    With ``blur_px`` None the estimator is :func:`subpixel_edges` (window ``half``, ``plateau`` px levels,
    a closed form); otherwise :func:`refine_step_fit` with that blur, run on a clean step with the texture added.

    Parameters
    ----------
    plane, samples, half, plateau, lut
        As given to :func:`subpixel_edges` (``half`` the final window half-size).
    mask : ndarray (N,) bool
        The samples the line fit kept.
    door_skip_px, door_side : int
        On an arris line the door side beside the edge is the arris strip, whose shading is no texture
        (a rounding's runs from dark to bright across it): its texture is read ``door_skip_px`` farther
        out, beyond the strip, on the side ``door_side`` (+1: increasing ``along``).

    Returns
    -------
    TextureBias
        NaN fields when fewer than 8 samples are usable.
    """
    P = oriented(plane, samples.axis)
    h = half + 1
    reach = max(2 * (half + plateau), 2 * h) + n_shifts + 2
    skip = max(int(door_skip_px), 0)
    R = reach + skip  # the gathered half-window: the door side's profile starts skip px farther out
    skip_plus, skip_minus = (skip, 0) if door_side > 0 else (0, skip)
    # Mean profiles over the scan lines (the line fit's outliers are already out) of the two halves of
    # the edge and of the whole edge, the step between the profiles' ends, and the distance between the
    # halves' mean scan lines
    profiles = (
        *pixel_buffer(P),
        P.shape[0],
        P.shape[1],
        samples.scan,
        samples.along,
        np.ascontiguousarray(mask, np.bool_),
        samples.valid,
        max_lines,
        R,
        plateau,
        lut if lut is not None else NO_LUT,
    )
    if blur_px is None:
        # the area estimator's error on each mean profile, both sides (closed form), and its RMS: all
        # compiled in one call (the Python between the steps cost more than they did)
        off, tilt = _area_texture_bias(*profiles, reach, skip_plus, skip_minus, n_shifts, half)
        return TextureBias(off, tilt)
    Ts, D, lever, n_ok = _texture_profiles(*profiles)
    if n_ok < 8 or not D > 0:
        return TextureBias(float("nan"), float("nan"))
    # the step fit's error on a clean step of this contrast with this texture on one side
    # (every profile's every shift in one fit: the rows are fitted independently)
    profs = np.stack(
        [
            p
            for T in Ts
            for p in (T[R + 1 + skip_plus : R + 1 + skip_plus + reach], T[: R - skip_minus][::-1][:reach])
        ]
    )
    bounds = np.arange(-h, h + 2, dtype=np.float64) - 0.5
    C0, _, _ = _pixel_step(bounds, np.zeros(1), max(float(blur_px), 0.05))
    k = np.arange(-h, h + 1)
    o = np.arange(h + 1, h + 1 + n_shifts)
    tex = profs[:, o[:, None] + k[None, :] - 1]
    tex = tex - tex.mean(axis=2, keepdims=True)
    rows = (C0[None] * (D + tex)).reshape(-1, k.size)
    err = _step_fit(rows, np.zeros(rows.shape[0]), bounds, max(float(blur_px), 0.05))
    err = err.reshape(profs.shape[0], o.size)
    pbs = np.stack([np.concatenate([err[2 * i], err[2 * i + 1]]) for i in range(len(Ts))])
    off, tilt = _texture_sigmas(pbs, n_shifts, lever)
    return TextureBias(off, tilt)


def _texture_warm_up(k, *extra) -> None:
    for buf, table in warm_up_planes(40):
        for plateau in (1, 2):
            on = np.ones(10, np.bool_)
            k(buf, 1, 40, 40, 40, np.arange(10), np.full(10, 20.3), on, on, 128, 10, plateau, table, *extra)


@kernel(_texture_warm_up)
def _texture_profiles(
    buf, pitch_along, pitch_scan, n_along, n_scan, scan, along, mask, valid, max_lines, R, plateau, lut
):
    """The mean profiles of :func:`texture_bias`, compiled (:mod:`doorloc.vision.jit`).

    The scan lines: those with ``mask``, ``valid`` and a finite ``along``, at most ``max_lines`` of them
    spread evenly (``np.linspace``'s indices). Profile ``i`` is ``P[round(along[i]) - R + j, scan[i]]`` for
    ``j <= 2 R`` (``buf``, pitches as :func:`_area_edges`), mapped by ``lut`` (empty: none); only profiles
    wholly inside the image count. Returns ``(Ts, D, lever, n)``: ``Ts`` (3, 2 R + 1) the float64 means of
    the profiles of both halves, of the upper and of the lower half of the scan lines (sorted; numpy's sums,
    row after row), ``D`` the median step between the profiles' two end plateaus (``plateau`` px each),
    ``lever`` the distance between the halves' mean scan lines and ``n`` the profiles counted (``Ts`` zero
    and ``D``, ``lever`` NaN below 8).
    """
    length = 2 * R + 1
    Ts = np.zeros((3, length))
    picked = np.empty(scan.size, np.int64)
    m = 0
    for i in range(scan.size):
        if mask[i] and valid[i] and np.isfinite(along[i]):
            picked[m] = i
            m += 1
    if m < 8:
        return Ts, np.nan, np.nan, 0
    if m > max_lines:  # a mean profile needs no more: np.linspace(0, m - 1, max_lines).astype(int)
        step = (m - 1) / (max_lines - 1)
        for q in range(max_lines - 1):
            picked[q] = picked[int(q * step)]
        picked[max_lines - 1] = picked[m - 1]
        m = max_lines
    rows = np.empty(m, np.int64)
    start = np.empty(m, np.int64)
    n = 0
    for q in range(m):
        i = picked[q]
        s0 = int(np.rint(along[i])) - R
        if s0 >= 0 and s0 + length - 1 < n_along:
            rows[n] = i
            start[n] = s0
            n += 1
    if n < 8:
        return Ts, np.nan, np.nan, n
    vals = np.empty((n, length), np.float32)
    steps = np.empty(n, np.float32)
    for r in range(n):
        base = scan[rows[r]] * pitch_scan
        for j in range(length):
            vals[r, j] = grey(lut, buf[(start[r] + j) * pitch_along + base])
        a = np.float32(0.0)
        b = np.float32(0.0)
        for j in range(plateau):
            a += vals[r, j]
            b += vals[r, length - plateau + j]
        steps[r] = abs(b / np.float32(plateau) - a / np.float32(plateau)) if plateau > 1 else abs(b - a)
    # the median step (np.median's value)
    srt = np.sort(steps)
    k = n // 2
    D = float(srt[k]) if n % 2 else float((srt[k - 1] + srt[k]) / np.float32(2.0))  # in float32, as median
    order = np.argsort(scan[rows])
    lo_sum = 0
    hi_sum = 0
    for q in range(n):
        r = order[q]
        t = 2 if q < k else 1  # Ts[2]: the lower half's, Ts[1]: the upper's
        for j in range(length):
            Ts[t, j] += vals[r, j]
        if q < k:
            lo_sum += scan[rows[r]]
        else:
            hi_sum += scan[rows[r]]
    for j in range(length):
        Ts[2, j] /= k
        Ts[1, j] /= n - k
        Ts[0, j] = 0.5 * (Ts[2, j] + Ts[1, j])
    lever = hi_sum / (n - k) - lo_sum / k
    return Ts, D, lever, n


@kernel(lambda k: _texture_warm_up(k, 30, 0, 0, 12, 3))
def _area_texture_bias(
    buf,
    pitch_along,
    pitch_scan,
    n_along,
    n_scan,
    scan,
    along,
    mask,
    valid,
    max_lines,
    R,
    plateau,
    lut,
    reach,
    skip_plus,
    skip_minus,
    n_shifts,
    half,
):
    """:func:`texture_bias`'s ``(offset_sigma_px, tilt_sigma)`` for the area estimator (window ``half``),
    compiled: the mean profiles (:func:`_texture_profiles`, the first arguments), then on each and each side
    (beyond the edge: from ``R + 1 + skip_plus``; before it, outwards: from ``R - 1 - skip_minus``), at the
    shifts ``o = half + plateau .. half + plateau + n_shifts - 1``, the closed form of the estimator's error
    on texture alone: the window sum of pixels ``o + 1 .. o + half`` minus ``half`` times the mean of the
    plateau beyond it, over the step ``D``; their RMS (numpy's sums). NaN without 8 profiles or a step.
    """
    Ts, D, lever, n = _texture_profiles(
        buf, pitch_along, pitch_scan, n_along, n_scan, scan, along, mask, valid, max_lines, R, plateau, lut
    )
    if n < 8 or not D > 0:
        return np.nan, np.nan
    pbs = np.empty((3, 2 * n_shifts))
    c = np.zeros(reach + 1)
    first = half + plateau
    for t in range(3):
        for side in range(2):
            for j in range(reach):
                x = Ts[t, R + 1 + skip_plus + j] if side == 0 else Ts[t, R - skip_minus - 1 - j]
                c[j + 1] = c[j] + x
            for q in range(n_shifts):
                o = first + q
                win = c[o + half] - c[o]
                lev = (c[o + half + plateau] - c[o + half]) / plateau
                pbs[t, side * n_shifts + q] = (win - half * lev) / D
    return _texture_sigmas(pbs, n_shifts, lever)


@kernel(lambda k: k(np.ones((3, 24)), 12, 2.0))
def _texture_sigmas(pbs, n_shifts, lever):
    """:class:`TextureBias`'s two figures from the estimator's errors ``pbs`` (3, 2 n_shifts): on the whole
    edge's mean profile, its upper and its lower half's, each side's ``n_shifts`` shifts in a row. Both
    sides add (independent textures): the RMS over the shifts of each side, summed in quadrature, for the
    offset; the same of the halves' difference over ``lever`` for the tilt (NaN without a lever). numpy's
    sums (:func:`doorloc.vision.jit.pairwise_sum`); both estimators' callers share it."""
    n = n_shifts
    sq = np.empty(2 * n)
    for j in range(2 * n):
        sq[j] = pbs[0, j] * pbs[0, j]
    off = math.sqrt(pairwise_sum(sq, 0, n) / n + pairwise_sum(sq, n, n) / n)
    tilt = np.nan
    if lever > 0:
        for j in range(2 * n):
            d = pbs[1, j] - pbs[2, j]
            sq[j] = d * d
        tilt = math.sqrt(pairwise_sum(sq, 0, n) / n + pairwise_sum(sq, n, n) / n) / lever
    return off, tilt


def _abs_step_sums_warm_up(k) -> None:
    for dtype in (np.uint8, np.uint16):
        for ax in (0, 1):
            k(np.zeros((40, 40), dtype)[2:30, 3:33], ax)


@kernel(_abs_step_sums_warm_up)
def _abs_step_sums(crop, ax):
    """``np.abs(np.diff(crop, axis=ax)).sum(axis=1 - ax)`` of an integer image, as int64 (exact), compiled."""
    h, w = crop.shape
    if ax == 1:
        out = np.zeros(w - 1, np.int64)
        for r in range(h):
            for c in range(w - 1):
                out[c] += abs(np.int64(crop[r, c + 1]) - np.int64(crop[r, c]))
    else:
        out = np.zeros(h - 1, np.int64)
        for r in range(h - 1):
            acc = 0
            for c in range(w):
                acc += abs(np.int64(crop[r + 1, c]) - np.int64(crop[r, c]))
            out[r] = acc
    return out


def _block_step_ratio_warm_up(k) -> None:
    for dtype in (np.uint8, np.uint16):
        k(np.zeros((40, 40), dtype)[2:36, 3:38], 5, 7, 1.0, 0.05)


@kernel(_block_step_ratio_warm_up)
def _block_step_ratio(crop, u0, v0, scale_to_8bit, min_excess):
    """:func:`block_artifact_ratio` of an integer ``crop`` (at most 256 px a side) whose first pixel is
    ``(u0, v0)``, compiled: the same float32 means (exact integer sums, :func:`_abs_step_sums`) and medians."""
    sc = np.float32(scale_to_8bit)
    out = 0.0
    for ax in (1, 0):
        s = _abs_step_sums(crop, ax)
        n = np.float32(crop.shape[1 - ax])
        o = u0 if ax == 1 else v0
        n_on = 0
        for i in range(s.size):
            n_on += (o + i) % 8 == 7
        on_d = np.empty(n_on, np.float32)
        off_d = np.empty(s.size - n_on, np.float32)
        a = b = 0
        for i in range(s.size):
            d = (np.float32(s[i]) / n) * sc
            if (o + i) % 8 == 7:
                on_d[a] = d
                a += 1
            else:
                off_d[b] = d
                b += 1
        on, off = median_in_place(on_d), median_in_place(off_d)
        out = max(out, on / max(off, 1e-3) if on - off >= min_excess else 1.0)
    return out


def block_artifact_ratio(
    plane: np.ndarray,
    centre_px: np.ndarray,
    half: int = 96,
    scale_to_8bit: float = 1.0,
    min_excess: float = 0.05,
) -> float:
    """How much stronger the grey-level steps between 8x8 pixel blocks are than those inside them, near a point.

    A JPEG round trip quantizes each 8x8 block on its own, which leaves steps at the block boundaries:
    the median over the boundary columns (rows) of the mean absolute difference to the next column (row),
    over the median of the same elsewhere, is about 1 for an image that never was a JPEG (1.0-1.2 on
    rendered ones at any noise) and 1.5 or (nearly noise-free) far more for JPEG quality 88. The larger
    of the two directions is returned; NaN when the window holds too few pixels. Where the boundary
    steps exceed the others by less than ``min_excess`` grey levels (0-255 scale; a noise-free image that
    never was a JPEG has all its medians near 0), the ratio is taken as 1.
    """
    cu, cv = float(centre_px[0]), float(centre_px[1])
    if not (math.isfinite(cu) and math.isfinite(cv)):
        return float("nan")
    u0, v0 = max(int(cu) - half, 0), max(int(cv) - half, 0)
    crop = plane[v0 : v0 + 2 * half, u0 : u0 + 2 * half]
    if min(crop.shape) < 32:
        return float("nan")
    if crop.dtype.kind in "ui" and crop.dtype.itemsize <= 2 and max(crop.shape) <= 256:
        # Integer differences summed exactly (compiled): the float32 mean's sums are integers below
        # 2**24 (exact), so this is the same mean for a fraction of the work (and no transposed copy).
        return float(_block_step_ratio(crop, u0, v0, scale_to_8bit, min_excess))
    out = []
    for ax, o in ((1, u0), (0, v0)):
        arr = crop if ax == 1 else crop.T
        d = np.abs(np.diff(arr.astype(np.float32), axis=1)).mean(axis=0) * scale_to_8bit
        boundary = (o + np.arange(d.size)) % 8 == 7
        on, off = median(d[boundary]), median(d[~boundary])
        out.append(on / max(off, 1e-3) if on - off >= min_excess else 1.0)
    return max(out)
