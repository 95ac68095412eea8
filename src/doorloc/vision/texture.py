"""How much the surface texture beside an edge can move its reader: :func:`texture_bias`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.vision.blurred_step import face_slope_step_fit, pixel_step, step_fit
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.jit import grey, kernel, pairwise_sum
from doorloc.vision.sampling import NO_LUT, oriented, pixel_buffer, warm_up_planes

__all__ = ["TextureBias", "texture_bias"]


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
    face_slope_half_px: int | None = None,
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
    a closed form); otherwise :func:`refine_step_fit` with that blur, run on a clean step with the texture
    added, with the face's level sloped on a window of ``face_slope_half_px`` each side where that is
    given (:func:`doorloc.vision.blurred_step.face_slope_step_fit`).

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
    # why many parameters: the edge's window as the estimator read it (half, plateau, lut) and the texture's settings, keywords with defaults as the edge models, the doubts, the response check and the reference test pass them
    P = oriented(plane, samples.axis)
    h = half + 1 if face_slope_half_px is None or blur_px is None else int(face_slope_half_px)
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
    sides = (R, reach, skip_plus, skip_minus)
    return _step_fit_texture_bias(profiles, sides, h, n_shifts, blur_px, face_slope_half_px is not None)


def _step_fit_texture_bias(
    profiles: tuple,
    sides: tuple[int, int, int, int],
    h: int,
    n_shifts: int,
    blur_px: float,
    face_sloped: bool = False,
) -> TextureBias:
    """:func:`texture_bias` for the step fit (:func:`refine_step_fit`, blur ``blur_px``, window ``h`` px each
    side, the face sloped where ``face_sloped``): the mean profiles (:func:`_texture_profiles` of
    ``profiles``, its arguments), each side's ``reach`` px beyond the edge, as texture beside a clean step
    (``sides``: ``R``, the profiles' half-window, ``reach``, and the px ``skip_plus``, ``skip_minus``
    skipped on each side)."""
    R, reach, skip_plus, skip_minus = sides
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
    errors = _step_fit_errors(profs, D, h, n_shifts, blur_px, face_sloped)
    off, tilt = _texture_sigmas(errors, n_shifts, lever)
    return TextureBias(off, tilt)


def _step_fit_errors(
    profs: np.ndarray, D: float, h: int, n_shifts: int, blur_px: float, face_sloped: bool = False
) -> np.ndarray:
    """:func:`texture_bias`'s errors of the step fit (window ``h`` px each side of the edge, blur ``blur_px``)
    on a clean step of contrast ``D`` with the texture of ``profs`` (each mean profile's two sides, beyond
    the edge and before it, outwards, in turn) on one side, at ``n_shifts`` shifts beyond the window: (the
    profiles, 2 n_shifts), each side's shifts in a row."""
    bounds = np.arange(-h, h + 2, dtype=np.float64) - 0.5
    C0, _, _ = pixel_step(bounds, np.zeros(1), max(float(blur_px), 0.05))
    k = np.arange(-h, h + 1)
    o = np.arange(h + 1, h + 1 + n_shifts)
    tex = profs[:, o[:, None] + k[None, :] - 1]
    tex = tex - tex.mean(axis=2, keepdims=True)
    rows = (C0[None] * (D + tex)).reshape(-1, k.size)
    sigma = max(float(blur_px), 0.05)
    zero = np.zeros(rows.shape[0])
    # (the texture is on the step's bright side, increasing coordinates: the face's)
    err = (
        face_slope_step_fit(rows, zero, bounds, sigma, 1)
        if face_sloped
        else step_fit(rows, zero, bounds, sigma)
    )
    err = err.reshape(profs.shape[0], o.size)
    return np.stack([np.concatenate([err[2 * i], err[2 * i + 1]]) for i in range(profs.shape[0] // 2)])


def _texture_warm_up(k, *extra) -> None:
    for buf, table in warm_up_planes(40):
        for plateau in (1, 2):
            on = np.ones(10, np.bool_)
            k(buf, 1, 40, 40, 40, np.arange(10), np.full(10, 20.3), on, on, 128, 10, plateau, table, *extra)


# (flat arguments: a numba kernel over the plane's buffer, :mod:`doorloc.vision.jit`)
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
    # why many parameters: a numba nopython kernel reading the image buffer by its pitches: the buffer, its layout, the scan lines with their masks and the profile's reach, plateau and look-up table pass as arrays and scalars (no dataclass in nopython code)
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


# (flat arguments: a numba kernel over the plane's buffer, :mod:`doorloc.vision.jit`)
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
    # why many parameters: a numba nopython kernel: _texture_profiles' arguments first (it calls it), then the area estimator's reach, skipped sides, shifts and window; nopython code takes no dataclass
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
