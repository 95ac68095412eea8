"""The arris lines: per scan line, the edge point on an arris's outer border, from the strip's fitted deficit
(:func:`doorloc.vision.arris_model.fit_strip_profile`) and then the strip's fitted shape fitted to the line with
its two levels free (:func:`_line_borders`, compiled). Units: pixels along the scan line; the caller moves the
points to the sharp corner's line by the geometry (:mod:`doorloc.vision.arris_geometry`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from doorloc.vision.arris_geometry import ArrisGeometry
from doorloc.vision.arris_model import FIT_LINES, StripFit, fit_strip_profile
from doorloc.vision.arris_strip_kernels import pixel_terms_fill
from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS
from doorloc.vision.edge_samples import EdgeSamples, ScanWindow
from doorloc.vision.edges import DITHERING_NOISE_LEVELS
from doorloc.vision.jit import kernel, pairwise_sum
from doorloc.vision.sampling import gather_profiles, oriented
from doorloc.vision.stated_light import StatedLight
from doorloc.vision.strip_prior import deficit_prior

__all__ = ["StripWindow", "arris_edges"]


def _line_borders(
    vals: np.ndarray,
    x: np.ndarray,
    border0: np.ndarray,
    width: np.ndarray,
    levels: np.ndarray,
    blur_px: float,
    n_iter: int = 6,
) -> np.ndarray:
    """Each scan line's outer border from the fitted strip shape: its place, its two levels free.

    ``vals`` (N, P) are the lines' profiles in linear light (background first), ``x`` (P,) their pixel
    centres, ``border0`` (N,) a start, ``width`` (N,) the strip's width, px; ``levels`` (C,) the strip
    cells' relative levels and ``blur_px`` the blur of :func:`fit_strip_profile`. Per line: the profile
    ``A + D s(x - b)``, with ``s`` the fitted shape (background 0 | strip cells | face 1, blurred and
    pixel-integrated), fitted in ``b`` (Gauss-Newton) with ``A`` and ``D`` solved linearly at each step.

    Why not the area estimate: it weighs every pixel of the window alike, so the texture of the hinge
    face inside the window (wood grain running along the edge and wandering across it) moves each line's
    edge by its integral: on the effects fixtures 0.2-0.7 px along the reference arris, which tilted the
    line (yaw up to 0.05 deg off) and bent it near the corner (refused ``corner_hidden``). The model
    weighs pixels by how much the border's place changes them: the strip's outer border (background to
    strip, where no face texture lies) pins it; the face's texture only enters through ``D``.
    Returns NaN for a line whose fit fails (no contrast, or a step beyond half a pixel on its last
    iteration). Compiled (:func:`_line_borders_compiled`): as array code, ~25 (N, P) array operations
    and the (N, P, J) pixel terms an iteration.
    """
    n_cells = levels.size
    frac = np.arange(n_cells + 1) / n_cells
    jumps = np.diff(np.concatenate([[0.0], levels, [1.0]]))  # (C + 1,) each boundary's step
    edges = np.concatenate([x[:1] - 0.5, x + 0.5])
    return _line_borders_compiled(
        np.ascontiguousarray(vals, np.float64),
        np.ascontiguousarray(edges, np.float64),
        np.array(border0, np.float64),
        np.ascontiguousarray(width, np.float64),
        frac,
        np.ascontiguousarray(jumps, np.float64),
        max(float(blur_px), 0.05),
        STEP_TAIL_SIGMAS,
        n_iter,
    )


def _line_borders_warm_up(k) -> None:
    vals = np.tile(np.linspace(10.0, 100.0, 12), (3, 1))
    edges = np.arange(13.0) - 0.5
    k(
        vals,
        edges,
        np.full(3, 5.0),
        np.full(3, 2.0),
        np.linspace(0, 1, 4),
        np.full(4, 0.25),
        0.8,
        STEP_TAIL_SIGMAS,
        6,
    )


@kernel(_line_borders_warm_up)
def _line_borders_compiled(vals, edges, b, w_in, frac, jumps, sigma, tail_sigmas, n_iter):
    """:func:`_line_borders`' iterations (``b`` (N,) updated in place): per line the shape and its slope
    from its boundaries' pixel terms (:func:`pixel_terms_fill`), never as (N, P, J) arrays; each line's sums in numpy's pairwise order (:func:`jit.pairwise_sum`), the
    shape's sum over boundaries in their order (the array code's matrix product summed in BLAS's)."""
    # why many parameters: a numba nopython kernel: the profiles, pixel edges, start borders, widths, cell boundaries, jumps, blur, tail and iteration count pass as arrays and scalars (no dataclass in nopython code); _line_borders prepares them
    n, n_p = vals.shape
    n_j = jumps.size
    ok = np.empty(n, np.bool_)
    w = np.empty(n)
    for i in range(n):
        ok[i] = math.isfinite(b[i]) and math.isfinite(w_in[i])
        if not ok[i]:
            b[i] = 0.0
        w[i] = w_in[i] if ok[i] else 0.0
    step = np.zeros(n)
    D = np.full(n, np.nan)
    bounds = np.empty((1, 1, n_j))
    sig = np.full(1, sigma)
    prim = np.empty((1, 1, n_p, n_j))
    d_b = np.empty((1, 1, n_p, n_j))
    d_s = np.empty((1, 1, n_p, n_j))
    shape = np.empty(n_p)
    dshape = np.empty(n_p)
    t = np.empty((4, n_p))
    for _ in range(n_iter):
        big = 0.0
        for i in range(n):
            for j in range(n_j):
                bounds[0, 0, j] = b[i] + w[i] * frac[j]
            pixel_terms_fill(edges, bounds, sig, tail_sigmas, prim, d_b, d_s)
            shape[:] = 0.0
            dshape[:] = 0.0
            for j in range(n_j):
                for p in range(n_p):
                    shape[p] += prim[0, 0, p, j] * jumps[j]
                    dshape[p] += d_b[0, 0, p, j] * jumps[j]
            # A and D by least squares on the line: [1, shape]
            s_mean = pairwise_sum(shape, 0, n_p) / n_p
            v_mean = pairwise_sum(vals[i], 0, n_p) / n_p
            for p in range(n_p):
                sc = shape[p] - s_mean
                t[0, p] = sc * sc
                t[1, p] = sc * (vals[i, p] - v_mean)
            ss = pairwise_sum(t[0], 0, n_p)
            D[i] = pairwise_sum(t[1], 0, n_p) / max(ss, 1e-12) if ss > 1e-12 else np.nan
            A = v_mean - D[i] * s_mean
            # the border's Gauss-Newton step, the levels projected out (variable projection)
            for p in range(n_p):
                t[2, p] = D[i] * dshape[p]
            j_mean = pairwise_sum(t[2], 0, n_p) / n_p
            for p in range(n_p):
                t[2, p] = t[2, p] - j_mean  # Jc
                t[3, p] = t[2, p] * (shape[p] - s_mean)
            k = pairwise_sum(t[3], 0, n_p) / max(ss, 1e-12)
            for p in range(n_p):
                jp = t[2, p] - k * (shape[p] - s_mean)
                t[0, p] = jp * jp
                t[1, p] = jp * ((A + D[i] * shape[p]) - vals[i, p])
            jj = pairwise_sum(t[0], 0, n_p)
            s = -pairwise_sum(t[1], 0, n_p) / max(jj, 1e-18) if jj > 1e-18 else np.nan
            s = -0.5 if s < -0.5 else (0.5 if s > 0.5 else s)
            step[i] = s
            if math.isfinite(s):
                b[i] = b[i] + s
                big = max(big, abs(s))
        if big < 1e-4:
            break
    for i in range(n):
        good = (
            ok[i] and math.isfinite(step[i]) and abs(step[i]) < 0.5 and math.isfinite(D[i]) and abs(D[i]) > 0
        )
        if not good:
            b[i] = np.nan
    return b


@dataclass(frozen=True)
class StripWindow:
    """How :func:`arris_edges` reads an arris strip's windows.

    Attributes
    ----------
    lines : ScanWindow
        The scan lines across the strip's outer border and its predicted position on each; ``half`` the
        window's half-size beyond the strip, ``plateau`` the samples on each side for the plateau levels,
        ``door_side`` +1 when the door (strip, then face) lies at increasing ``along`` (its
        ``level_smooth`` is not used: each line's levels are its own, see ``level_px``).
    blur0 : float
        Starting blur for the shading fit, px.
    search : bool
        The prediction may be off by up to the strip's width (a first pass on a coarse pose, whose edge
        may be the strip's inner border): widen the window by that much on both sides.
    level_px : int or None
        Samples of each plateau, nearest the window, whose mean is each scan line's two levels in its
        area estimate (None: all ``plateau``). The profile fit uses all ``plateau`` samples (the face
        beside the strip pins its brightness); each line's levels taken farther from the window pick up
        the texture along the edge (wood grain).
    line_fit : bool
        Each line's border from the fitted strip shape (:func:`_line_borders`) where that fit holds, the
        area estimate elsewhere; False: the area estimate on every line.
    light : StatedLight or None
        The cell's light (its direction in the cell frame and its doubt), for a rounding's shading; None:
        free.
    split_check : bool
        The strip is also fitted on the scan lines between those picked, and the two fits' disagreement
        joins its deficit's doubt (:func:`_strip_shading`); False where no one reads that doubt (the strips
        read again at trial camera exponents only for their places and misfits).
    blur_prior : (float, float) or None
        The blur the door's other strips read (mean, sd px), a prior on this strip's
        (:func:`doorloc.vision.strip_posterior.strip_blur_priors`); None: the blur free.
    """

    lines: ScanWindow
    blur0: float = 1.0
    search: bool = False
    level_px: int | None = None
    line_fit: bool = True
    light: StatedLight | None = None
    split_check: bool = True
    blur_prior: tuple[float, float] | None = None

    @property
    def door_side(self) -> int:
        """+1 when the door lies at increasing ``along``."""
        return self.lines.door_side

    @property
    def plateau(self) -> int:
        """Samples on each side for the plateau levels."""
        return self.lines.plateau

    @property
    def scale_to_8bit(self) -> float:
        """Grey-level scale to 0-255."""
        return self.lines.scale_to_8bit

    @property
    def lut(self) -> np.ndarray | None:
        """Linearising look-up table (camera response), or None."""
        return self.lines.lut


@dataclass(frozen=True)
class _StripProfiles:
    """The scan lines' profiles across an arris strip, mirrored so that the door lies at increasing index
    (linear light), and what the area estimate takes of them.

    ``vals`` (N, L) the profiles, window and plateaus; ``c0`` (N,) each window's centre (rounded predicted
    border, px); ``pad`` the search's widening, px; ``w`` (N,) the strip's width, px; ``rel_e`` (N,) the
    predicted border relative to ``c0`` (mirrored, px); ``A``, ``B``, ``D`` (N,) the plateaus' levels and
    step; ``D_e``, ``S`` (N,) the area estimate's step (of its ``nl`` samples beside the window) and sum;
    ``good`` (N,) the lines in the image with a step; ``noise`` (N,) the plateaus' noise; ``half`` the
    window's half-size beyond the strip, px; ``clipped`` (N,) the lines with two or more pixels at the image's
    top code (white-clipped) inside the window.
    """

    vals: np.ndarray
    c0: np.ndarray
    half: int
    pad: int
    w: np.ndarray
    rel_e: np.ndarray
    A: np.ndarray
    B: np.ndarray
    D: np.ndarray
    D_e: np.ndarray
    S: np.ndarray
    nl: int
    good: np.ndarray
    noise: np.ndarray
    clipped: np.ndarray

    @property
    def length(self) -> int:
        """Samples of each profile."""
        return int(self.vals.shape[1])


def arris_edges(
    window: StripWindow,
    band_px: np.ndarray,
    geom: ArrisGeometry,
) -> tuple[EdgeSamples, StripFit | None]:
    """Outer border of an arris strip on each scan line (module docstring, step 3).

    Parameters
    ----------
    window : StripWindow
        The scan lines across the strip's outer border, the door's side, the plateaus, the grey scale and
        how the strip is fitted.
    band_px : ndarray (N,)
        Strip width on each scan line, px.
    geom : ArrisGeometry
        The arris's geometry.

    Returns
    -------
    samples : EdgeSamples
        The outer border per scan line (``along``), step ``B - A`` signed along ``along``.
    fit : StripFit or None
        The strip's shading; None when it could not be fitted (then no sample is valid).
    """
    lines = window.lines
    axis, scan, centre = lines.axis, np.asarray(lines.scan, int), np.asarray(lines.centre, float)
    prof = _strip_profiles(oriented(lines.plane, axis), scan, centre, lines.half, band_px, window)
    fit, bias = _strip_shading(prof, geom, window)
    if fit is None:
        nan = np.full(len(scan), np.nan)
        return EdgeSamples(axis, scan, nan, nan, nan, nan, nan, np.zeros(len(scan), bool)), None
    e_mirror, in_window = _line_edges(prof, fit, bias, centre, window)
    c0, door_side, scale_to_8bit, A, B, D = (
        prof.c0,
        window.door_side,
        window.scale_to_8bit,
        prof.A,
        prof.B,
        prof.D,
    )
    along = c0 + door_side * e_mirror
    valid = prof.good & np.isfinite(along) & in_window
    # a strip whose highlight clips at white has no shading to fit: how many of its lines do (the gate's)
    fit = replace(fit, clipped_share=float(np.mean(prof.clipped[prof.good])) if prof.good.any() else 0.0)
    nan = np.full(len(scan), np.nan)
    # the strongest step of the fitted shape (background | strip cells | face), per line in grey levels:
    # what locates the point where the face's own step is faint (a strip darker or brighter than both sides)
    jumps = np.diff(np.concatenate([[0.0], fit.levels, [1.0]]))
    strip_contrast = float(np.max(np.abs(jumps))) * np.abs(D) * scale_to_8bit
    return (
        EdgeSamples(
            axis,
            scan,
            np.where(valid, along, np.nan),
            D * door_side * scale_to_8bit,
            prof.noise * scale_to_8bit,
            nan,
            np.maximum(A, B) * scale_to_8bit,
            valid,
            strip_contrast,
        ),
        fit,
    )


def _strip_profiles(
    P: np.ndarray,
    scan: np.ndarray,
    centre: np.ndarray,
    half: int,
    band_px: np.ndarray,
    window: StripWindow,
) -> _StripProfiles:
    """Each scan line's profile across the strip, mirrored to the door's side, and its levels: ``P`` the
    plane oriented along the scan (:func:`oriented`), image px: ``scan`` the lines, ``centre`` the
    predicted outer border along them, ``half`` the window's half-size beyond the strip, ``band_px`` the
    strip's width."""
    door_side, plateau, lut, level_px = window.door_side, window.plateau, window.lut, window.level_px
    w = np.maximum(np.asarray(band_px, float), 0.0)
    finite = np.isfinite(centre) & np.isfinite(w)
    n_extra = int(math.ceil(np.nanmax(w))) if np.any(finite) else 0
    pad = n_extra if window.search else 0
    c0 = np.round(np.where(finite, centre, 0.0)).astype(int)
    length = 2 * (half + plateau + pad) + 1 + n_extra
    if door_side > 0:
        vals, inside = gather_profiles(P, scan, c0 - half - plateau - pad, length, lut=lut)
    else:  # mirror so that the door side is at increasing index
        vals, inside = gather_profiles(P, scan, c0 + half + plateau + pad - length + 1, length, lut=lut)
        vals, inside = vals[:, ::-1], inside[:, ::-1]
    vals = vals.astype(np.float64)
    left, right = vals[:, :plateau], vals[:, -plateau:]
    A, B = left.mean(axis=1), right.mean(axis=1)
    D = B - A
    nl = plateau if level_px is None else int(np.clip(level_px, 1, plateau))
    # the area estimate's levels: the nl samples of each plateau next to the window
    A_e, B_e = (
        vals[:, plateau - nl : plateau].mean(axis=1),
        vals[:, length - plateau : length - plateau + nl].mean(axis=1),
    )
    D_e = B_e - A_e
    core = vals[:, plateau : length - plateau]
    S = (core - A_e[:, None]).sum(axis=1)
    rel_e = (centre - c0) * door_side  # predicted border relative to c0, mirrored coordinates
    good = finite & inside.all(axis=1) & (np.abs(D) > 0)
    noise = np.sqrt(0.5 * (left.var(axis=1) + right.var(axis=1)))
    clipped = np.count_nonzero(core >= _white_level(P.dtype, lut), axis=1) >= 2
    return _StripProfiles(vals, c0, half, pad, w, rel_e, A, B, D, D_e, S, nl, good, noise, clipped)


def _white_level(dtype: np.dtype, lut: np.ndarray | None) -> float:
    """The value a white-clipped pixel has in the strip's profiles: the top code of the (8- or 16-bit) plane,
    through the linearising table where there is one."""
    top = int(np.iinfo(dtype).max)
    if lut is None:
        return float(top)
    return float(lut[min(top, len(lut) - 1)])


#: two picks of a strip's scan lines whose fitted deficits differ by more than this many of their joint
#: sigma read the strip in different valleys (:func:`_strip_shading`)
SPLIT_SIGMAS = 3.0


def _strip_shading(
    prof: _StripProfiles, geom: ArrisGeometry, window: StripWindow
) -> tuple[StripFit | None, float]:
    """The strip's shading fitted to up to ``FIT_LINES`` of the profiles (:func:`fit_strip_profile`), and
    the area estimator's bias on the fitted profiles (px, mirrored; 0 without a fit)."""
    plateau, w, nl, length = window.plateau, prof.w, prof.nl, prof.length
    idx = np.nonzero(prof.good)[0]
    fit = None
    if idx.size >= 5:
        n = min(idx.size, FIT_LINES)
        at = np.linspace(0, idx.size - 1, n)
        fit, pick = _fit_picked(prof, geom, window, idx[at.round().astype(int)])
        if fit is not None and window.split_check and idx.size >= 2 * n:
            # The same strip read from the lines between those picked: where the two land in different
            # valleys (their deficits, and the border's place, apart by more than their doubts) the
            # posterior gave one of two about equal valleys all the weight (measured: bench_arris_range.py --sets round
            # --seed 9100 --thickness 80, seed 9119, a 2.37 mm rounding: one pick in five placed the bottom
            # end's border 0.8 px out, deficit 0.50 +- 0.009 against 0.57, and was answered 0.17 mm off at
            # 3.5 sigma). Their disagreement beyond what their own doubts explain joins the deficit's doubt.
            between = (at + 0.5 * (at[1] - at[0])).clip(0, idx.size - 1)
            other, _ = _fit_picked(prof, geom, window, idx[between.round().astype(int)])
            if other is not None:
                apart = abs(fit.deficit - other.deficit)
                if apart > SPLIT_SIGMAS * math.hypot(fit.deficit_sigma, other.deficit_sigma):
                    fit = replace(fit, deficit_sigma=math.hypot(fit.deficit_sigma, apart))
    bias = 0.0
    if fit is not None:
        fit = replace(fit, grey_misfit=_grey_misfit(prof, pick, fit, window))
        # The area estimator on the fitted, noise-free profiles: what the window's ends and the plateaus'
        # blur tails cost it (the strip's two steps differ, so they do not cancel as on a plain step).
        mod = fit.model
        a_m = mod[:, plateau - nl : plateau].mean(axis=1)
        b_m = mod[:, length - plateau : length - plateau + nl].mean(axis=1)
        s_m = (mod[:, plateau : length - plateau] - a_m[:, None]).sum(axis=1)
        e_m = (length - 2 * plateau - 0.5) - s_m / (b_m - a_m) - w[pick] * fit.model_deficit
        bias = float(np.median(e_m - (fit.border - plateau)))
    return fit, bias


def _fit_picked(
    prof: _StripProfiles, geom: ArrisGeometry, window: StripWindow, pick: np.ndarray
) -> tuple[StripFit | None, np.ndarray]:
    """The strip's shading fitted to the profiles ``pick`` (:func:`fit_strip_profile`), and the rows it took
    (finite profiles across a strip)."""
    plateau, scale_to_8bit = window.plateau, window.scale_to_8bit
    vals, A, B, D, noise, w = prof.vals, prof.A, prof.B, prof.D, prof.noise, prof.w
    pad, length = prof.pad, prof.length
    with np.errstate(divide="ignore", invalid="ignore"):
        r = (vals[pick] - A[pick, None]) / D[pick, None]
    # the rows the fit takes (finite profiles across a strip): its bias and grey-level misfit below are
    # read on the same rows as its fitted profiles
    kept = (
        np.all(np.isfinite(r), axis=1) & np.isfinite(prof.rel_e[pick]) & np.isfinite(w[pick]) & (w[pick] > 0)
    )
    pick, r = pick[kept], r[kept]
    x = np.arange(length, dtype=float)
    outer = plateau + pad + prof.half + prof.rel_e[pick]
    # profile noise, normalised; at least the quantisation of the 8-bit scale (a noise-free render)
    nz = float(np.median(np.maximum(noise[pick], 0.3 / scale_to_8bit) / np.abs(D[pick])))
    # the rounding that the noise does not dither (DITHERING_NOISE_LEVELS), normalised (one
    # grey level taken as one unit of the linearised scale: a first-order figure under a camera response)
    dn = float(np.median(noise[pick])) * scale_to_8bit
    undithered = min(max(1.0 - dn / DITHERING_NOISE_LEVELS, 0.0), 1.0)
    shared = undithered * float(np.median((1.0 / 12.0) / (D[pick] * scale_to_8bit) ** 2))
    prior = deficit_prior(float(np.median(B[pick])), float(np.median(A[pick])))
    fit = fit_strip_profile(
        r,
        x,
        outer,
        w[pick],
        geom,
        nz,
        window.blur0,
        search_px=float(pad),
        prior=prior,
        shared=shared,
        light=window.light,
        blur_prior=window.blur_prior,
    )
    return fit, pick


#: least grey-level noise of a strip's plateaus, 0-255 (a noise-free render: the quantisation's)
_GREY_NOISE_FLOOR = 0.3


def _grey_misfit(prof: _StripProfiles, pick: np.ndarray, fit: StripFit, window: StripWindow) -> float:
    """The fitted profiles' residual RMS in the camera's grey levels over the plateaus' grey-level noise
    (:attr:`StripFit.grey_misfit`): model and profiles (linear light) turned back through the table they
    were linearised with (``window.lines.lut``; the grey levels themselves where it is None), on the
    profiles ``pick`` the fit took (its fitted profiles' rows).

    Why in grey levels: the fit weighs linear light evenly, where a camera's noise is not even (an exponent
    above 1 shrinks the noise of the dark side and stretches the bright side's), so its misfit, taken over
    the plateaus' mean noise, falls or rises with the exponent tried as much as with how well the shape
    fits. On 130 chamfered doors of the arris bench (chamfer, ambient and small sets, seeds 10100-13115)
    read at five exponents across the factor 2.2, that misfit was lowest at a wrong exponent on many
    doors (the camera's up to 1.73 times the lowest); this figure was lowest at the camera's exponent
    within 1.03 on every door, with the cell told right or told 2.2 times the camera's."""
    plateau, s8, lut = window.plateau, window.scale_to_8bit, window.lines.lut
    vals = prof.vals[pick]
    lin_model = prof.A[pick, None] + prof.D[pick, None] * fit.model
    if lut is None:
        seen, model = vals, lin_model
    else:
        codes = np.arange(lut.size, dtype=np.float64)
        seen, model = np.interp(vals, lut, codes), np.interp(lin_model, lut, codes)
    # each plateau's scatter about its own level, pooled over both plateaus of every profile
    spread = [np.var(seen[:, :plateau] * s8, axis=1, ddof=1), np.var(seen[:, -plateau:] * s8, axis=1, ddof=1)]
    noise = max(float(np.sqrt(np.mean(np.concatenate(spread)))), _GREY_NOISE_FLOOR)
    return float(np.sqrt(np.mean((model - seen) ** 2))) * s8 / noise


def _line_edges(
    prof: _StripProfiles, fit: StripFit, bias: float, centre: np.ndarray, window: StripWindow
) -> tuple[np.ndarray, np.ndarray]:
    """Each line's outer border relative to its window's centre ``c0`` (px, mirrored to the door's side)
    and whether it lies in its window: the area estimate with the fitted deficit, refined by the fitted
    strip shape (:func:`_line_borders`) where ``window.line_fit``; ``centre`` the predicted border, image
    px."""
    plateau, door_side = window.plateau, window.door_side
    vals, w, c0, good, rel_e = prof.vals, prof.w, prof.c0, prof.good, prof.rel_e
    half, pad, length = prof.half, prof.pad, prof.length
    with np.errstate(divide="ignore", invalid="ignore"):
        K = (
            length - 2 * plateau - 0.5
        )  # door-side end of the window (core index units; core starts at c0 - half - pad)
        e_area = K - prof.S / prof.D_e - w * fit.deficit - bias - (half + pad)  # relative to c0
    # Each line's border from the fitted strip shape (:func:`_line_borders`), started at the area estimate
    # (vals index units: the window's first pixel is index 0, c0 at plateau + pad + half). The shape is
    # the best fit's, whose deficit may differ from the posterior's in use (a flat valley): the fit
    # starts from the area estimate with the best fit's deficit, and its border moves back by the
    # difference.
    x0 = plateau + pad + half
    if not window.line_fit:
        e_model = e_area
    else:
        e_model = (
            _line_borders(
                np.where(good[:, None], vals, 0.0),
                np.arange(length, dtype=float),
                e_area + x0 + w * (fit.deficit - fit.model_deficit),
                w,
                fit.levels,
                fit.blur_px,
            )
            + w * (fit.model_deficit - fit.deficit)
            - x0
        )
    with np.errstate(invalid="ignore"):
        # the model's border where its fit held and stayed near the area estimate's; that elsewhere (a
        # line whose profile the strip's mean shape does not describe)
        e_mirror = np.where(np.abs(e_model - e_area) <= 1.0 + 0.25 * w, e_model, e_area)
        # a line whose area estimate lies in its window has an edge point (the window was placed for it)
        in_window = np.abs(door_side * e_area + c0 - centre) <= half + pad
    if window.line_fit:
        # A strip much darker or brighter than both sides (a chamfer in shadow: face 150, strip 85,
        # background 133) leaves the area estimate ill-conditioned (its deficit is divided by a contrast the
        # strip dwarfs): on such a bottom end 40 % of the lines' estimates fell out of their 3-px windows
        # and the door was refused edge_not_straight with every other point within 0.1 px of its line
        # (bench_surfaces --sets combined --seed 500, image 36). Those lines' borders are fitted from the
        # predicted border instead (the window's centre), and kept where the fit lands in the window.
        lost = good & ~in_window & np.isfinite(w)
        if np.any(lost):
            shift = w[lost] * (fit.deficit - fit.model_deficit)
            e_lost = (
                _line_borders(
                    vals[lost],
                    np.arange(length, dtype=float),
                    rel_e[lost] + x0 + shift,
                    w[lost],
                    fit.levels,
                    fit.blur_px,
                )
                - shift
                - x0
            )
            with np.errstate(invalid="ignore"):
                held = np.isfinite(e_lost) & (
                    np.abs(door_side * e_lost + c0[lost] - centre[lost]) <= half + pad
                )
            e_mirror[np.flatnonzero(lost)[held]] = e_lost[held]
            in_window[np.flatnonzero(lost)[held]] = True
    return e_mirror, in_window
