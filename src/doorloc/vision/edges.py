"""The area readers of edge points along integer scan lines: a plain step and a step beside a band (an arris
strip).

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
when the window is centred on the edge. ``A`` and ``B`` may be averaged along the edge against noise, where
they do not change along it (:func:`doorloc.vision.plateau_levels.level_smoothing`).

The other readers and what they share live beside this module: the edge points' type
(:mod:`doorloc.vision.edge_samples`), the blurred pixel step and its per-line fit
(:mod:`doorloc.vision.blurred_step`), the far-face fit (:mod:`doorloc.vision.far_face`), the texture term
(:mod:`doorloc.vision.texture`), the JPEG block measure (:mod:`doorloc.vision.jpeg_blocks`) and the width
of an edge's transition (:mod:`doorloc.vision.transition`); the models that choose among them,
:mod:`doorloc.vision.edge_models`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.vision.edge_samples import EdgeSamples, ScanWindow
from doorloc.vision.jit import grey, kernel, median_in_place
from doorloc.vision.plateau_levels import level_smoothing, running_level_mean
from doorloc.vision.sampling import (
    NO_LUT,
    Axis,
    flat_view,
    gather_profile_rows,
    gather_profiles,
    oriented,
    smooth_along,
    smooth_along_rows,
    warm_up_planes,
)

__all__ = [
    "DITHERING_NOISE_LEVELS",
    "AreaEdgeReader",
    "subpixel_edges",
    "subpixel_edges_banded",
]

#: plateau noise (grey levels, 1-sigma) from which the noise dithers the rounding to grey levels; under it
#: the pixels of one sub-pixel phase round alike, and averaging them does not average the rounding away
#: (the response reading and the arris strip fit both ask)
DITHERING_NOISE_LEVELS = 0.5


def _area_edges_warm_up(k) -> None:
    for buf, table in warm_up_planes(8):
        for scan in (np.arange(8), np.arange(16)[::2]):  # (a strided selection of scan lines too)
            k(buf, 1, 8, 8, 8, scan, np.full(8, 1), np.ones(8, bool), 2, 1, table, 1, 1.0)


@kernel(_area_edges_warm_up)
def _area_edges(
    buf,
    pitch_along,
    pitch_scan,
    n_along,
    n_scan,
    scan,
    start,
    finite,
    half,
    plateau,
    lut,
    level_smooth,
    quantum,
):
    """The area estimate of :func:`subpixel_edges` with flat plateaus, compiled (:mod:`doorloc.vision.jit`).

    Profile ``i`` holds ``P[start[i] + j, scan[i]] = buf[(start[i] + j) * pitch_along + scan[i] * pitch_scan]``
    for ``j < 2 (half + plateau) + 1`` (clamped to the image), mapped by ``lut`` (float32; empty: none).
    Returns ``along`` (NaN where not valid), the two levels ``A``, ``B`` (float32 values unless smoothed
    along the edge, over the scan lines each side that ``level_smoothing`` chooses, at most
    ``level_smooth``; ``quantum``: an 8-bit grey level in the plane's units), ``noise`` (float32) and
    ``valid``: the numbers of the numpy branch of :func:`subpixel_edges` up to the order of its float sums.
    """
    # why many parameters: a numba nopython kernel over the plane's flat buffer takes arrays and scalars only
    # why long: one compiled pass per profile (levels, noise, area) and the levels' running sums, as numpy's
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
        # each level averaged along the edge (a profile that leaves the image takes no part), over as many
        # scan lines as its changes along the edge allow
        gap = np.empty(n)
        m = 0
        for i in range(n):
            if inside[i] and np.isfinite(A[i]) and np.isfinite(B[i]):
                gap[m] = abs(B[i] - A[i])
                m += 1
        step = median_in_place(gap[:m]) if m else np.nan
        for X in (A, B):
            k = level_smoothing(X, inside, start, level_smooth, half, step, quantum)
            if k > 0:
                X[:] = running_level_mean(X, inside, k)
    along = np.empty(n)
    valid = np.empty(n, np.bool_)
    _area_along(A, B, S, start, finite, inside, half, plateau, along, valid)
    return along, A, B, noise, valid


@kernel(inline=True)
def _area_along(A, B, S, start, finite, inside, half, plateau, along, valid):
    """The area estimate of every profile into ``along`` (NaN where not ``valid``) from its levels ``A``,
    ``B``, its window's sum ``S`` and its first sample ``start`` (:func:`_area_edges`)."""
    # why many parameters: a numba kernel takes arrays and scalars, and this one writes two of them
    w = 2 * half + 1
    for i in range(A.size):
        a = A[i]
        b = B[i] - a
        # S - (2 half + 1) A: the area between the profile and the first level
        sa = S[i] - w * a
        den = b + np.sqrt(b * b) * np.sign(b)
        e = start[i] + plateau + 2 * half + 0.5 - 2.0 * sa / den if den != 0 else np.nan
        c0 = start[i] + half + plateau
        ok = finite[i] and inside[i] and np.isfinite(e) and abs(b) > 0 and abs(e - c0) <= half
        valid[i] = ok
        along[i] = e if ok else np.nan


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
    # why many parameters: the public area reader (photometric fit, board response, tests) keeps its keywords
    windows, flat = _area_windows(plane, axis, scan, centre, half, plateau)
    scan = windows.scan
    if not slope_smooth > 0 and flat is not None:
        # flat plateaus (the default): compiled, one pass over each profile (_area_edges)
        along, A, B, noise, valid = _area_edges_compiled(windows, flat, lut, level_smooth, scale_to_8bit)
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
    along, A, B, noise, valid = _area_edges_numpy(windows, lut, level_smooth, slope_smooth, scale_to_8bit)
    step = B - A
    width = np.full(
        scan.size, np.nan
    )  # per-sample widths are too noisy to use; see transition.transition_width
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


@dataclass(frozen=True)
class _AreaWindows:
    """The windows :func:`subpixel_edges` reads: the plane ``P`` oriented so that profiles run along its axis
    0, the scan lines ``scan``, each profile's first sample ``start`` (the low plateau's), where the predicted
    edge is ``finite``, the window's centre ``c0`` (the prediction rounded), its ``half`` width and the
    ``plateau`` beside it, px."""

    P: np.ndarray
    scan: np.ndarray
    start: np.ndarray
    finite: np.ndarray
    c0: np.ndarray
    half: int
    plateau: int


def _area_windows(
    plane: np.ndarray, axis: Axis, scan: np.ndarray, centre: np.ndarray, half: int, plateau: int
) -> tuple[_AreaWindows, tuple[np.ndarray, int, int] | None]:
    """:func:`subpixel_edges`'s windows, and the plane's pixel buffer where its compiled branch can read it
    (an 8- or 16-bit plane stored contiguously or transposed; None: the numpy branch)."""
    P = oriented(plane, axis)
    centre = np.asarray(centre, float)
    finite = np.isfinite(centre)
    c0 = np.round(np.where(finite, centre, 0.0)).astype(int)
    windows = _AreaWindows(P, np.asarray(scan, int), c0 - half - plateau, finite, c0, half, plateau)
    flat = flat_view(P) if plane.dtype in (np.uint8, np.uint16) else None
    return windows, flat


def _area_edges_compiled(
    windows: _AreaWindows,
    flat: tuple[np.ndarray, int, int],
    lut: np.ndarray | None,
    level_smooth: int,
    scale_to_8bit: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`subpixel_edges` with flat plateaus over the plane's pixel buffer ``flat`` (buffer, pitch along
    and across the scan lines): ``(along, A, B, noise, valid)``, the edge (px, NaN where not valid), the two
    levels and the plateaus' noise in the plane's grey levels."""
    w = windows
    buf, pitch_along, pitch_scan = flat
    along, A, B, noise, valid = _area_edges(
        buf,
        pitch_along,
        pitch_scan,
        w.P.shape[0],
        w.P.shape[1],
        w.scan,
        w.start,
        w.finite,
        w.half,
        w.plateau,
        lut if lut is not None else NO_LUT,
        level_smooth if w.scan.size else 0,
        1.0 / scale_to_8bit,  # an 8-bit grey level in the plane's units
    )
    if not (level_smooth > 0 and w.scan.size):  # unsmoothed levels stay float32, as in the numpy branch
        A, B = A.astype(np.float32), B.astype(np.float32)
    return along, A, B, noise, valid


class AreaEdgeReader:
    """:func:`subpixel_edges` (flat plateaus, no level smoothing) prepared once for a plane and fixed scan lines
    and predicted edges, and read through any number of response tables: a camera model's fit places one
    photograph's edges with every model it tries (hundreds of times), and the windows, the plane's buffer
    and their checks are the same each time. :meth:`along` gives what ``subpixel_edges(plane, axis, scan,
    centre, half, plateau, lut=lut)`` gives as ``along`` and ``valid``, to the bit."""

    def __init__(
        self, plane: np.ndarray, axis: Axis, scan: np.ndarray, centre: np.ndarray, half: int, plateau: int = 4
    ) -> None:
        self._args = (plane, axis, scan, centre, half, plateau)
        # (None: subpixel_edges's numpy branch, which the reader then takes whole)
        self._windows, self._flat = _area_windows(plane, axis, scan, centre, half, plateau)

    def along(self, lut: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each scan line's edge (px along its scan, NaN where not valid) and whether it is valid, the grey
        levels read through ``lut`` (float32 table, :func:`doorloc.vision.sampling.linearizing_lut`; None:
        as stored)."""
        if self._flat is None:
            es = subpixel_edges(*self._args, lut=lut)
            return es.along, es.valid
        along, _, _, _, valid = _area_edges_compiled(self._windows, self._flat, lut, 0, 1.0)
        return along, valid


def _area_edges_numpy(
    windows: _AreaWindows, lut: np.ndarray | None, level_smooth: int, slope_smooth: int, scale_to_8bit: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`subpixel_edges` in numpy (any plane; sloped plateaus): ``(along, A, B, noise, valid)``, the edge
    (px, not yet NaN where not valid), the two levels and the plateaus' noise in the plane's grey levels."""
    w = windows
    half, plateau, scan = w.half, w.plateau, w.scan
    length = 2 * (half + plateau) + 1
    vals, inside_ok = gather_profile_rows(w.P, scan, w.start, length, lut=lut)
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
        A, B = _smoothed_levels(A, B, inside_ok, w.start, level_smooth, half, 1.0 / scale_to_8bit)
    step = B - A
    L = _window_length(left, right, core, A, B, half, slope_smooth)
    along = w.start + plateau + 2 * half + 0.5 - L
    valid = w.finite & inside_ok & np.isfinite(along) & (np.abs(step) > 0)
    # The estimate must lie inside its window; otherwise the transition was not captured.
    valid &= np.abs(along - w.c0) <= half
    return along, A, B, noise, valid


def _smoothed_levels(
    A: np.ndarray,
    B: np.ndarray,
    inside: np.ndarray,
    start: np.ndarray,
    level_smooth: int,
    half: int,
    quantum: float,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_area_edges_numpy`'s levels ``A``, ``B`` averaged along the edge, each over the scan lines
    :func:`doorloc.vision.plateau_levels.level_smoothing` gives it (profiles not ``inside`` the image take
    no part; ``start``: each profile's first pixel)."""
    ok = inside & np.isfinite(A) & np.isfinite(B)
    step = float(np.median(np.abs(B - A)[ok])) if ok.any() else math.nan
    k = [
        int(level_smoothing(X.astype(np.float64), inside, start, level_smooth, half, step, quantum))
        for X in (A, B)
    ]
    AB = np.stack([A, B])
    AB = AB if inside.all() else np.where(inside, AB, np.nan)
    if k[0] == k[1] == level_smooth:
        A, B = smooth_along_rows(AB, level_smooth)
        return A, B
    out = [smooth_along_rows(AB[j : j + 1], k[j])[0] if k[j] > 0 else (A, B)[j] for j in range(2)]
    return out[0], out[1]


def _window_length(
    left: np.ndarray,
    right: np.ndarray,
    core: np.ndarray,
    A: np.ndarray,
    B: np.ndarray,
    half: int,
    slope_smooth: int,
) -> np.ndarray:
    """:func:`subpixel_edges`' area equation solved on each profile: the length ``L`` of its window beyond
    the edge (px), from the window's samples ``core`` (N, 2 half + 1), the plateaus ``left`` and ``right``
    (N, plateau) and their levels ``A``, ``B``; with ``slope_smooth``, the levels extrapolated under the
    transition along the plateaus' slopes."""
    plateau = left.shape[1]
    hp = half + 0.5
    if slope_smooth > 0 and plateau > 1 and A.size:
        # Plateau slopes (shading, wood grain parallel to the edge), smoothed along the edge: the levels
        # are extrapolated linearly under the transition instead of being assumed flat.
        kp = np.arange(plateau) - (plateau - 1) / 2.0
        den = float((kp * kp).sum())
        a1 = ((left - A[:, None]) * kp).sum(axis=1) / den
        b1 = ((right - B[:, None]) * kp).sum(axis=1) / den
        if slope_smooth >= A.size:  # one slope per side for the whole edge (smooth shading)
            a1 = np.full(A.size, np.nanmedian(a1))
            b1 = np.full(A.size, np.nanmedian(b1))
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
    return L


def subpixel_edges_banded(
    window: ScanWindow, band_px: np.ndarray, band_slope: float = 0.0, sharp: bool = False
) -> tuple[EdgeSamples, float]:
    """Outer edge of a step with a band of unknown, uniform grey level on its door side (a chamfered or
    rounded arris seen as a strip between the background and the hinge face).

    The profile is ``background A | band L, width w | face B``. With the band width ``w`` known from
    the geometry (arris size projected), the area over the window is ``(L - A) w + (B - A)(K - e - w)``,
    ``K`` the window's door-side end; ``L`` is measured as the median grey level at the band's centre
    over the whole edge. Then ``e = K - w - (S - (L - A) w) / (B - A)``.

    Parameters
    ----------
    window : ScanWindow
        The plane, scan lines, predicted edges and window as for :func:`subpixel_edges`, and ``door_side``:
        +1 when the door (band, then face) lies at increasing ``along``.
    band_px : ndarray (N,)
        Band width on each scan line, px (>= 0).
    band_slope : float
        How the band width changes when the edge moves by 1 px towards the door side (0 for an arris
        strip; ``-(1 - k)`` for the far face's band, whose outer edge moves only ``k`` times as far).
        The area equation is solved with ``w = band_px + band_slope (e - centre)``.
    sharp : bool
        The image has no optical blur (pixels are pure area samples). A band narrower than 3 px may have no
        pixel wholly inside it; its level is then found as the one whose pixel-area model of the mixed
        pixels fits best (instead of being assumed mid-grey).

    Returns
    -------
    samples : EdgeSamples
        As :func:`subpixel_edges`; ``step`` is ``B - A`` signed along ``along``.
    band_level : float
        The band's grey level ``L`` (0-255 scale), NaN if it could not be measured.
    """
    p = _banded_profiles(window, band_px)
    half, door_side, c0, A, B, w = window.half, window.door_side, p.c0, p.A, p.B, p.w
    L = _band_level(p, band_slope, sharp)
    with np.errstate(divide="ignore", invalid="ignore"):
        # distance from the door-side end of the window back to the outer edge; a band too narrow to
        # measure anywhere is taken at mid-grey between the two sides (error at most half its width)
        rho = 1.0 - ((L - A) / (B - A) if np.isfinite(L) else 0.5)  # 1 - band level, relative
        K = (
            p.vals.shape[1] - 2 * window.plateau - 0.5
        )  # door-side end of the window, core index units (core starts at mirrored c0 - half)
        e_pred = half + p.rel_e
        # K - e = w rho + S / D with w = w_pred + slope (e - e_pred), solved for e. A band much brighter
        # than the face makes this ill-conditioned (the area hardly changes as the edge moves): then
        # nothing is returned (all samples invalid) and the caller measures the plain step instead.
        conditioned = 1.0 + band_slope * np.nanmedian(rho) >= 0.5
        e_mirror = (K - (w - band_slope * e_pred) * rho - p.S / (B - A)) / (1.0 + band_slope * rho)
        along = np.where(door_side > 0, c0 - half + e_mirror, c0 + half - e_mirror)
    step = (B - A) * door_side
    valid = p.finite & p.inside & np.isfinite(along) & (np.abs(B - A) > 0) & conditioned
    valid &= np.abs(along - p.centre) <= half
    nan = np.full(len(p.scan), np.nan)
    s8 = window.scale_to_8bit
    return (
        EdgeSamples(
            window.axis,
            p.scan,
            np.where(valid, along, np.nan),
            step * s8,
            p.noise * s8,
            nan,
            np.maximum(np.maximum(A, B), L if np.isfinite(L) else 0) * s8,
            valid,
        ),
        L * s8,
    )


@dataclass(frozen=True)
class _Banded:
    """:func:`subpixel_edges_banded`'s profiles, mirrored so that the door side lies at increasing index:
    their values ``vals`` (N, length), whether each lies wholly ``inside`` the image, where the prediction and
    the band width are ``finite``, the scan lines ``scan``, the predicted edge ``centre`` and its rounding
    ``c0`` (px along the scan line), the band's width ``w`` (px), the predicted edge relative to ``c0`` in
    mirrored coordinates ``rel_e``, the two levels ``A``, ``B`` (smoothed along the edge where asked), the
    window's area above ``A`` (``S``) and the plateaus' ``noise``, in the plane's grey levels."""

    vals: np.ndarray
    inside: np.ndarray
    finite: np.ndarray
    scan: np.ndarray
    centre: np.ndarray
    c0: np.ndarray
    w: np.ndarray
    rel_e: np.ndarray
    A: np.ndarray
    B: np.ndarray
    S: np.ndarray
    noise: np.ndarray
    half: int
    plateau: int


def _banded_profiles(window: ScanWindow, band_px: np.ndarray) -> _Banded:
    """The profiles of :func:`subpixel_edges_banded` (``band_px`` the band's width per scan line, px), read
    over the window, its plateaus and the widest band, and their levels."""
    half, plateau, door_side = window.half, window.plateau, window.door_side
    P = oriented(window.plane, window.axis)
    scan = np.asarray(window.scan, int)
    centre = np.asarray(window.centre, float)
    w = np.maximum(np.asarray(band_px, float), 0.0)
    finite = np.isfinite(centre) & np.isfinite(w)
    n_extra = int(math.ceil(np.nanmax(w))) if np.any(finite) else 0
    c0 = np.round(np.where(finite, centre, 0.0)).astype(int)
    length = 2 * (half + plateau) + 1 + n_extra
    if door_side > 0:
        start = c0 - half - plateau
        vals, inside = gather_profiles(P, scan, start, length, lut=window.lut)
    else:  # mirror so that the door side is at increasing index
        start = c0 + half + plateau
        vals, inside = gather_profiles(P, scan, start - length + 1, length, lut=window.lut)
        vals, inside = vals[:, ::-1], inside[:, ::-1]
    left = vals[:, :plateau]
    right = vals[:, -plateau:]
    core = vals[:, plateau : length - plateau]
    A = left.mean(axis=1)
    B = right.mean(axis=1)
    if window.level_smooth > 0 and scan.size:
        ok_in = inside.all(axis=1)
        A = smooth_along(np.where(ok_in, A, np.nan), window.level_smooth)
        B = smooth_along(np.where(ok_in, B, np.nan), window.level_smooth)
    rel_e = (centre - c0) * door_side  # predicted edge relative to c0, in mirrored coordinates
    S = (core - A[:, None]).sum(axis=1)
    noise = np.sqrt(0.5 * (left.var(axis=1) + right.var(axis=1)))
    all_inside = np.asarray(inside.all(axis=1))
    return _Banded(vals, all_inside, finite, scan, centre, c0, w, rel_e, A, B, S, noise, half, plateau)


def _band_level(p: _Banded, band_slope: float, sharp: bool) -> float:
    """The band's grey level (the plane's units, NaN where it cannot be measured): the grey value at the
    band's centre (linear interpolation), median over the edge, from the scan lines where the band is wide
    enough to hold a whole pixel; on a ``sharp`` image with none that wide, the level whose pixel-area model
    fits best (:func:`_band_level_from_pixels`)."""
    vals, w, finite, plateau, half = p.vals, p.w, p.finite, p.plateau, p.half
    length = vals.shape[1]
    pos = plateau + half + p.rel_e + w / 2.0  # index into vals
    i0 = np.clip(np.floor(pos).astype(int), 0, length - 2)
    fr = pos - i0
    mid = vals[np.arange(len(p.scan)), i0] * (1 - fr) + vals[np.arange(len(p.scan)), i0 + 1] * fr
    # A whole pixel inside the band; a band whose width follows the edge (far face) needs more room,
    # as its predicted position may still be off.
    wide = finite & (w >= (3.0 if band_slope else 2.0)) & p.inside
    L = float(np.median(mid[wide])) if np.any(wide) else float("nan")
    good = finite & p.inside
    if not np.isfinite(L) and sharp and np.any(good & (w > 0.2)):  # too narrow to hold a whole pixel
        L = _band_level_from_pixels(vals[good], p.A[good], p.B[good], p.S[good], w[good], plateau, half)
    return L


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
