"""Is the camera response what the cell file says? Measured on the shape of plain edges.

In linear light the transition of a plain step is the optical blur's edge response: symmetric about the
edge (a Gaussian or any even point-spread function, integrated over square pixels). The area estimator
puts the edge at the transition's centre of mass; the 50 % crossing of the same transition lies there
too. Grey levels linearised with the wrong exponent skew the transition: the pixel values at ``+d``
and ``-d`` from the centre no longer add up to one step.

:func:`fit_line_response` turns that into a measurement of the camera's response: the exponent ``g``
for which the raw grey levels raised to ``g`` give a symmetric transition (nothing of the renderer is
assumed, only an even point-spread function), with its standard error from the exponent's scatter over
blocks of scan lines (texture and shading beside the edge vary along it). :func:`combine_responses` pools the
plain lines of one image (one camera, one response). An edge along a pixel row or column (a door square
to the camera) samples its transition at one pixel phase only, where no pixel at ``+d`` has a partner at
``-d``: the mean transition is read between its pixels by a cubic spline, where the optical blur (1 px
and more) makes it smooth enough, with a floor on the exponent's standard error for the spline's own
error (:func:`_resampled_asymmetry`).

:func:`board_response` measures the same on the calibration photographs' chessboard edges (``doorloc
calibrate`` stores it with the camera model): a camera's response once, where hundreds of plain edges at
every phase are in view, so that doors whose edges cannot show it (arrises, a sharp door square to the
camera) need not doubt it by the full range of cameras' exponents.

What a response error does to the edge follows from the step model, not from a tuned factor:
:func:`edge_shift_px` is where the area estimator puts a Gaussian-blurred step between the line's two
measured plateaus, linearised with one exponent when the camera's is another. Locate uses it for the
response term of the uncertainty budget (``response_sigma_mm`` per line): where the fitted response
differs from the cell's beyond ``RESPONSE_ABSORB_SIGMAS`` standard errors on two edges or more (the
combination of the image's and, where the cell's exponent was measured, its ``camera.response_gamma_sigma``), locate
measures again with the fitted one (the error is absorbed) and the doubt left is the shift that the
exponent's standard error makes; otherwise the doubt is the shift between the cell's exponent and the
fitted one beyond twice that (a right cell keeps its small sigma), except for a reading between the
pixels (a door square to the camera), which is combined with the cell's exponent as known within
``locate.response_unmeasured_factor`` (:meth:`ResponseFit.with_unmeasured_claim`). Where every plain
edge admits a second exponent about as well (the asymmetry is not monotone in the exponent: :func:`_least_asymmetric`), the
image cannot tell the camera's: nothing is absorbed and the doubt is the largest shift of the readings.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.special import ndtr

from doorloc.vision.edges import DITHERING_NOISE_LEVELS, EdgeSamples, subpixel_edges
from doorloc.vision.jit import kernel, median_in_place, pairwise_sum
from doorloc.vision.sampling import Axis, gather_profiles, linearizing_lut, oriented

__all__ = [
    "RESPONSE_ABSORB_SIGMAS",
    "RESPONSE_GAMMA_RANGE",
    "RESPONSE_ONE_PHASE_MIN_BLUR_PX",
    "RESPONSE_PLAUSIBLE",
    "RESPONSE_SKEW_BLOCKS",
    "BoardResponse",
    "LineResponse",
    "ResponseFit",
    "board_response",
    "combine_responses",
    "at_one_phase",
    "edge_shift_px",
    "edge_shifts_px",
    "fit_board_response",
    "fit_line_response",
    "plateau_levels",
]

#: contiguous blocks along the line over which the skew is measured again, for its standard error
RESPONSE_SKEW_BLOCKS = 8
#: exponents searched for the camera's response (a camera's gamma lies well inside)
RESPONSE_GAMMA_RANGE = (0.4, 5.0)
#: half width of the window the transition is read over, in blur sigmas (plus 1.5 px)
RESPONSE_WINDOW_BLURS = 3.0
#: plateau pixels at each end of a profile that set its levels, and the scan lines (each side) they are
#: averaged over
RESPONSE_PLATEAU_PX = 3
RESPONSE_LEVEL_ROWS = 8
#: profiles the fit uses at most (every k-th along the line)
RESPONSE_MAX_PROFILES = 320
#: the smallest standard error of a line's exponent (8 blocks estimate a scatter to about +-25 %)
RESPONSE_SIGMA_FLOOR = 0.02
#: the fitted response replaces the cell's when it differs by more than this many standard errors
RESPONSE_ABSORB_SIGMAS = 4.0
#: an edge at one pixel phase (along a pixel row or column) is read between its pixels by interpolation
#: only from this optical blur on (Gaussian sigma, px; sharper transitions are not smooth on the pixel
#: scale), and its exponent's 1-sigma is at least this fraction of it (:func:`_resampled_asymmetry`):
#: on rendered doors square to the camera (wide random lighting and albedos, blur 1.1-1.7 px, exponents
#: 1.0-2.4) the readings were 23 % RMS off, and their pulls 1.0 RMS with this floor (1.7 with 0.1)
RESPONSE_ONE_PHASE_MIN_BLUR_PX = 1.0
RESPONSE_ONE_PHASE_SIGMA = 0.2
#: ... and, as the blur falls towards a pixel, at least this fraction of it times (1 px / blur)^3: the
#: spline between one phase's samples assumes a Gaussian spread, and the same steps blurred by OpenCV's
#: sampled Gaussian kernel instead of a continuous one read up to 47 / 27 / 15 % off at 1.0 / 1.2 /
#: 1.5 px, as the pixel phase went (a lens's spread is no Gaussian either)
RESPONSE_ONE_PHASE_PSF = 0.5
#: the exponents a camera's response has (a linear sensor 1.0, video and sRGB about 2.2-2.4): only a fit
#: inside is absorbed
RESPONSE_PLAUSIBLE = (0.8, 3.0)
#: another exponent whose transition is within this factor as symmetric as the best one's is a second
#: reading of the same edge (:func:`_least_asymmetric`)
RESPONSE_AMBIGUOUS_RATIO = 2.0


@dataclass(frozen=True)
class LineResponse:
    """The response exponent measured on one plain edge.

    Attributes
    ----------
    gamma, sigma : float
        The exponent that makes the edge's mean transition symmetric (raw grey levels, full scale 1,
        raised to it are proportional to light), and its 1-sigma.
    lo, hi : float
        The two plateaus' raw grey levels beside the window, full scale 1 (for :func:`edge_shift_px`).
    skew_px : float
        The skew with the exponent the estimate used (diagnostics).
    one_phase : bool
        Read at one pixel phase, between the pixels by interpolation (:func:`_resampled_asymmetry`).
    alternatives : tuple of float
        Other exponents that make the transition about as symmetric (:func:`_least_asymmetric`): the edge
        does not tell which one the camera has.
    shared_sigma : float
        The part of ``sigma`` that every line of the image shares (at one phase, the interpolation's
        error, which follows the lens's spread, the same on every edge): pooling lines does not average
        it down (:func:`combine_responses`).
    """

    gamma: float
    sigma: float
    lo: float
    hi: float
    skew_px: float
    one_phase: bool = False
    alternatives: tuple[float, ...] = ()
    shared_sigma: float = 0.0


@dataclass(frozen=True)
class ResponseFit:
    """The camera response of one image, pooled over its plain edges (:func:`combine_responses`).

    ``absorb`` says whether it differs from the cell's ``claimed`` exponent by more than
    ``RESPONSE_ABSORB_SIGMAS`` standard errors, measured on two edges at least (locate then measures
    again with ``gamma``). ``claimed_sigma`` is the claimed exponent's own 1-sigma where it was measured
    (``camera.response_gamma_sigma``), 0 where it was not. A measured claim is a second measurement of
    the same exponent, and the image's own replaces it where the two disagree beyond
    ``RESPONSE_ABSORB_SIGMAS`` joint sigmas (one of them is wrong, and the cell's is the older), or where
    their inverse-variance combination (:attr:`combined`) moves from the cell's by more than that many of
    its own sigmas (the image measured the exponent better than the calibration did). So a calibration
    as good as the image holds back an image whose edges differ by a few of their own sigmas (a real
    photograph's own sigma understates its scatter several times, :func:`board_response`), up to
    sqrt(2) times the unmeasured threshold, and a loose one does not hold back a better image.

    ``alternatives``: other exponents that every edge's transition admits about as well
    (:attr:`LineResponse.alternatives`): the image cannot tell which the camera has, and nothing is
    absorbed. ``one_phase``: a line of it was read between its pixels (:attr:`LineResponse.one_phase`),
    a reading that rests on the lens's spread being Gaussian.
    """

    gamma: float
    sigma: float
    claimed: float
    lines: tuple[str, ...]
    claimed_sigma: float = 0.0
    alternatives: tuple[float, ...] = ()
    one_phase: bool = False

    @property
    def disagreement(self) -> float:
        """``|gamma - claimed|`` in joint sigmas of the two measurements (the image's alone where the claim
        was not measured)."""
        return abs(self.gamma - self.claimed) / math.hypot(self.sigma, self.claimed_sigma)

    @property
    def combined(self) -> tuple[float, float, float]:
        """The exponent from this image's and, where measured, the cell's measurement (inverse variances),
        its 1-sigma, and that 1-sigma widened by their disagreement where it exceeds one joint sigma
        (Birge ratio, as :func:`combine_responses` does for the lines)."""
        if not self.claimed_sigma > 0:
            return self.gamma, self.sigma, self.sigma
        w_i, w_c = 1.0 / self.sigma**2, 1.0 / self.claimed_sigma**2
        se = 1.0 / math.sqrt(w_i + w_c)
        return (w_i * self.gamma + w_c * self.claimed) / (w_i + w_c), se, se * max(self.disagreement, 1.0)

    def with_unmeasured_claim(self, prior_sigma: float) -> tuple[float, float]:
        """The camera's exponent where the cell's (``claimed``) was not measured but is taken as known to
        ``prior_sigma`` (1 sigma): the image's reading (brought into ``RESPONSE_PLAUSIBLE``) and the claim
        by inverse variances, and its 1-sigma.

        A weak reading moves the exponent most of the way and keeps most of its sigma. Taking a reading
        within two of its sigmas of the claim as proof of it had left a cell of 1.0 for a 1.67 camera,
        read 1.65 +- 0.34 on a door square to the camera, 0.056 mm off at 4.4 sigma.
        """
        g, se, _ = replace(
            self, gamma=float(np.clip(self.gamma, *RESPONSE_PLAUSIBLE)), claimed_sigma=prior_sigma
        ).combined
        return g, se

    @property
    def absorb(self) -> bool:
        # two edges at least: one edge's texture can mimic a response, two rarely agree by chance
        # and a camera's response: below ~0.8 (darks lifted) no camera is made; such a fit is texture or
        # shading that the response cannot explain
        if (
            len(self.lines) < 2
            or self.alternatives
            or not RESPONSE_PLAUSIBLE[0] <= self.gamma <= RESPONSE_PLAUSIBLE[1]
        ):
            return False
        # (for a claim that was not measured the combination is the image's own reading, and the two
        # tests below are one: the reading beyond RESPONSE_ABSORB_SIGMAS of its sigmas)
        g, se, _ = self.combined
        return (
            abs(g - self.claimed) > RESPONSE_ABSORB_SIGMAS * se or self.disagreement > RESPONSE_ABSORB_SIGMAS
        )


@dataclass(frozen=True)
class _Transitions:
    """Raw profiles across one edge (full scale 1) and the edge's place in them, for the skew in ``g``.

    ``one_phase``: the edge points fall at one pixel phase (an edge along a pixel row or column), and
    :func:`_asymmetry` reads the transition between the pixels by interpolation. ``dithered``: the
    plateaus' noise (half a grey level or more) dithers the rounding to grey levels, which then averages
    out over the profiles (:func:`_least_asymmetric`).
    """

    raw: np.ndarray  # (N, 2 half + 1)
    offset: np.ndarray  # (N,) the window's first pixel centre minus the sub-pixel edge, px
    one_phase: bool = False
    dithered: bool = True


def _dithered(raw: np.ndarray, top: float) -> bool:
    """Whether raw profiles (full scale 1, ``top`` grey levels) have ``DITHERING_NOISE_LEVELS`` of noise or
    more on their plateaus (the median over the profiles of the end pixels' scatter about their mean)."""
    pk = RESPONSE_PLATEAU_PX
    ends = [raw[:, :pk], raw[:, -pk:]]
    var = sum(((e - e.mean(axis=1, keepdims=True)) ** 2).sum(axis=1) for e in ends) / (2 * pk - 2)
    return bool(np.median(np.sqrt(var)) * top >= DITHERING_NOISE_LEVELS)


def at_one_phase(offset_px: np.ndarray) -> bool:
    """Whether edge points at these sub-pixel offsets (px) miss a quarter of the pixel phases (an edge
    along a pixel row or column), where the mean transition cannot be read at every offset."""
    return np.unique(np.floor((np.asarray(offset_px) % 1.0) * 4.0)).size < 4


def _transitions(plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int) -> _Transitions | None:
    m = mask & samples.valid
    if int(m.sum()) < 10:
        return None
    P = oriented(plane, samples.axis)
    e = samples.along[m]
    c0 = np.round(e).astype(int)
    vals, inside = gather_profiles(P, samples.scan[m], c0 - half, 2 * half + 1)
    ok = inside.all(axis=1)
    if int(ok.sum()) < 10:
        return None
    top = 255.0 if plane.dtype == np.uint8 else 65535.0
    order = np.argsort(samples.scan[m][ok])  # contiguous blocks along the line
    raw = vals[ok][order].astype(np.float64) / top
    return _Transitions(raw, (c0[ok] - half - e[ok])[order].astype(np.float64), dithered=_dithered(raw, top))


def _skew(t: _Transitions, rows: np.ndarray | slice, g: float) -> float:
    """The skew (50 % crossing minus centre of mass of the mean transition, px) of the profiles ``rows`` with raw levels raised to ``g``."""
    vals = t.raw[rows] ** g
    off = t.offset[rows]
    d = np.diff(vals, axis=1)
    tot = d.sum(axis=1, keepdims=True)
    good = np.abs(tot[:, 0]) > 1e-9
    if int(good.sum()) < 3:
        return float("nan")
    # positions from the dark side to the bright one: the skew's sign then says which way the exponent
    # is off, whichever the edge's polarity
    pos = (np.arange(d.shape[1]) + 0.5 + off[good][:, None]) * np.sign(tot[good])
    d = d[good] / tot[good]
    bins = np.round(pos * 4).astype(int)
    lo = bins.min()
    acc = np.bincount((bins - lo).ravel(), weights=d.ravel())
    cnt = np.bincount((bins - lo).ravel())
    x = (np.arange(cnt.size) + lo) / 4.0
    filled = cnt > 0
    gm = np.interp(x, x[filled], acc[filled] / cnt[filled])
    if gm.sum() <= 0:
        return float("nan")
    w = gm / gm.sum()
    centre = float(np.sum(w * x))
    cum = np.cumsum(w) - 0.5 * w
    k = int(np.searchsorted(cum, 0.5))
    if k <= 0 or k >= x.size:
        return float("nan")
    f = (0.5 - cum[k - 1]) / max(cum[k] - cum[k - 1], 1e-12)
    return float(x[k - 1] + f * (x[k] - x[k - 1]) - centre)


def fit_line_response(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    used_gamma: float,
    blur_px: float = 0.0,
) -> LineResponse | None:
    """The camera's response exponent measured on one plain edge (module docstring).

    Parameters
    ----------
    plane : ndarray
        The luminance plane (raw grey levels, uint8 or uint16).
    samples, mask, half
        The line's edge points (``along`` is the sub-pixel edge), the points to use, the window's half
        width (px).
    used_gamma : float
        The exponent the edge points were measured with (the skew reported is at it).
    blur_px : float
        Optical blur (Gaussian sigma, px), for the window.

    Returns
    -------
    LineResponse or None
        None where the skew has no root in ``RESPONSE_GAMMA_RANGE`` or too few profiles are usable.
    """
    # The window holds the whole transition (3 blur sigmas each side) and plateaus at both ends.
    wide = max(half, int(math.ceil(RESPONSE_WINDOW_BLURS * max(blur_px, 0.0) + 1.5)))
    t = _transitions(plane, samples, mask, wide + RESPONSE_PLATEAU_PX)
    if t is None:
        return None
    one_phase = at_one_phase(t.offset)
    # Read between the pixels only where the optical blur itself makes the transition smooth (a line's
    # transition width is inflated by noise and texture: 2.6 px measured on a door blurred by 0.67 px,
    # whose two edges then read 0.63 and 3.4 for a linear camera).
    one_phase_blur = _one_phase_blur(t, used_gamma) if one_phase else float("nan")
    if one_phase and not one_phase_blur >= RESPONSE_ONE_PHASE_MIN_BLUR_PX:
        return None
    if t.raw.shape[0] > RESPONSE_MAX_PROFILES:  # evenly along the line: enough for the shape
        k = int(math.ceil(t.raw.shape[0] / RESPONSE_MAX_PROFILES))
        t = replace(t, raw=t.raw[::k], offset=t.offset[::k])
    t = replace(t, one_phase=one_phase)
    n_blocks = min(RESPONSE_SKEW_BLOCKS, t.raw.shape[0] // 12)
    if n_blocks < 3:
        return None
    # the standard error from the exponent's scatter over contiguous blocks of scan lines (texture and
    # shading beside the edge change slowly along it)
    blocks = np.repeat(
        np.arange(n_blocks), [len(b) for b in np.array_split(np.arange(t.raw.shape[0]), n_blocks)]
    )
    found = _exponent_with_scatter(t, blocks, n_blocks)
    if found is None:
        return None
    g, se, alternatives = found
    # an exponent no camera has is no second reading (the primary one is kept whatever it is: the
    # doubt takes the nearest plausible one)
    alternatives = tuple(a for a in alternatives if RESPONSE_PLAUSIBLE[0] <= a <= RESPONSE_PLAUSIBLE[1])
    shared = 0.0
    if one_phase:
        # the interpolation's own error, which the blocks share (one phase, one spline error) and the
        # image's other edges too (one lens)
        shared = g * max(RESPONSE_ONE_PHASE_SIGMA, RESPONSE_ONE_PHASE_PSF / one_phase_blur**3)
        se = math.hypot(se, shared)
    lo, hi = plateau_levels(plane, samples, mask & samples.valid, wide)
    return LineResponse(
        g, se, lo, hi, _skew(t, slice(None), used_gamma), one_phase, alternatives, shared_sigma=shared
    )


def _one_phase_blur(t: _Transitions, used_gamma: float) -> float:
    """The optical blur (Gaussian sigma, px) of a transition sampled at one pixel phase, NaN if unreadable.

    The profiles linearised with ``used_gamma``, normalised by their plateaus and averaged (the noise
    and the texture along the edge average out), differ from pixel to pixel by the blur's line spread
    integrated over two pixels (a Gaussian of variance ``sigma^2 + 1/6``): the curvature of its
    logarithm at the peak's three pixels gives it at any phase (exact for a Gaussian blur; the plateaus'
    slopes, which inflate a width measured over the window, do not reach the peak). A step-model fit
    (:func:`doorloc.vision.edges.step_blur`) gives the same and cost ~6 ms per line.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.exp(used_gamma * np.log(t.raw))
    pk = RESPONSE_PLATEAU_PX
    lo, hi = v[:, :pk].mean(axis=1), v[:, -pk:].mean(axis=1)
    span = hi - lo
    ok = np.abs(span) > 1e-9
    if int(ok.sum()) < 3:
        return float("nan")
    step = np.diff(((v[ok] - lo[ok, None]) / span[ok, None]).mean(axis=0))
    j = int(np.argmax(step))
    if not (1 <= j <= step.size - 2 and np.all(step[j - 1 : j + 2] > 0)):
        return float("nan")
    a = np.log(step[j - 1 : j + 2])
    curv = float(a[0] - 2.0 * a[1] + a[2])
    return math.sqrt(max(-1.0 / curv - 1.0 / 6.0, 0.0)) if curv < 0 else float("nan")


def _exponent_with_scatter(
    t: _Transitions, blocks: np.ndarray, n_blocks: int
) -> tuple[float, float, tuple[float, ...]] | None:
    """The exponent of least asymmetry of all the profiles ``t``, its standard error from the scatter of
    the exponents of the blocks (``blocks`` (N,): each profile's block), at least ``RESPONSE_SIGMA_FLOOR``,
    and the other exponents about as symmetric (:func:`_least_asymmetric`); None where either of the first
    two is not found."""
    g_hat, alternatives = _least_asymmetric(t, np.geomspace(*RESPONSE_GAMMA_RANGE, 25))
    if not math.isfinite(g_hat):
        return None
    per_block = _least_asymmetric_blocks(t, g_hat * np.geomspace(1 / 1.6, 1.6, 11), blocks, n_blocks)
    per_block = per_block[np.isfinite(per_block)]
    if per_block.size < 3:
        return None
    se = float(np.std(per_block, ddof=1)) / math.sqrt(per_block.size)
    return g_hat, max(se, RESPONSE_SIGMA_FLOOR), alternatives


def _asymmetry(
    t: _Transitions, gammas: np.ndarray, blocks: np.ndarray | None = None, n_blocks: int = 0
) -> np.ndarray:
    """How far the profiles, with raw levels raised to each of ``gammas``, are from a step blurred by an
    even spread: shape ``(G,)``, or ``(G, n_blocks)`` over the rows of each block (``blocks`` (N,) the
    block of each profile).

    Each profile is normalised by its plateaus (the mean of ``RESPONSE_PLATEAU_PX`` pixels at each end,
    averaged over ``2 RESPONSE_LEVEL_ROWS + 1`` neighbouring scan lines: single noisy end pixels raised to
    the trial exponent would make the normalised noise, and so this measure's floor, depend on the
    exponent and pull its minimum) and centred on its own area estimate (exact for a pixel-integrated
    step under any even point-spread function); in linear light the pixel values at distances ``+d`` and
    ``-d`` from that centre then add up to 1. The measure is the mean square of that sum's departure
    from 1 over 1/8-px bins of ``d`` filled on both sides (NaN if fewer than 4 are, or fewer than 3
    profiles have two distinct plateaus).

    All exponents (and blocks) are evaluated in one call of two compiled kernels
    (:func:`_normalised_profiles`, :func:`_paired_asymmetry`): this runs on every plain edge of every image.
    Blocks share the whole line's shading tilt and level smoothing (a slow shading is the line's, and a
    block's own median of a few dozen plateau slopes would only add noise to its exponent).
    """
    with np.errstate(divide="ignore"):
        v = np.exp(np.asarray(gammas, float)[:, None, None] * np.log(t.raw)[None])  # (G, N, W)
    N = v.shape[1]
    n, centre, good = _normalised_profiles(v, RESPONSE_PLATEAU_PX, min(2 * RESPONSE_LEVEL_ROWS + 1, N))
    if t.one_phase:
        return _resampled_asymmetry(n, centre, good, blocks, n_blocks)
    blk = blocks.astype(np.int64) if blocks is not None else np.zeros(N, dtype=np.int64)
    out = _paired_asymmetry(n, centre, good, blk, max(n_blocks, 1))
    return out if blocks is not None else out[:, 0]


# The two steps of _asymmetry are compiled: written with numpy they were ~30 passes over (G, N, W) arrays
# of a few hundred kB, ~1.2 ms per call and 9 calls per edge-measuring image (11 ms of its ~27). The raw
# levels are raised to the exponents by numpy (its vectorised exp); the kernels give the numbers the
# numpy code gave, bit for bit: its sums in its order (numpy's pairwise sum along a row, scipy's running
# sum in uniform_filter1d), its median, its bincount (tests/vision/test_jit.py holds them to the numpy
# version kept in tests/vision/numpy_reference.py).


def _normalised_warm_up(k) -> None:
    k(np.full((2, 5, 10), 0.5), 3, 3)


@kernel(_normalised_warm_up)
def _normalised_profiles(v, pk, size):
    """:func:`_asymmetry`'s profiles ``v`` (G, N, W) (light: raw levels raised to each exponent) without
    their shading tilt, normalised by their plateaus (``pk`` px at each end, averaged over ``size`` scan
    lines) over the inner ``L = W - 2 pk`` pixels: ``n`` (G, N, L), each profile's area centre (G, N,
    index units) and whether its plateaus differ (G, N)."""
    G, N, W = v.shape
    L = W - 2 * pk
    n = np.empty((G, N, L))
    centre = np.empty((G, N))
    good = np.zeros((G, N), dtype=np.bool_)
    xs = np.empty(pk)
    xx = 0.0
    for j in range(pk):
        xs[j] = j - (pk - 1) / 2.0
        xx += xs[j] * xs[j]  # (exact: a sum of squares of multiples of 1/2)
    rel = np.empty(2 * N)
    scale = np.empty(W)
    ends = np.empty((2, N))
    row = np.empty(L)
    for g in range(G):
        # Shading across the edge (an illumination gradient, vignetting) multiplies the light by a slope
        # that tilts both plateaus alike and would read as asymmetry: take it out, as the median relative
        # slope of the plateau pixels over the line.
        any_nan = False
        for e in range(2):
            o = 0 if e == 0 else W - pk
            for i in range(N):
                sl = 0.0
                for j in range(pk):
                    sl += xs[j] * v[g, i, j + o]
                sl = sl / xx
                lev = 0.0
                for j in range(1, pk):
                    lev += v[g, i, j + o]
                lev = lev + v[g, i, o]
                m = lev / pk
                r = sl / (m if (m > 1e-9 or np.isnan(m)) else 1e-9)  # np.maximum(m, 1e-9)
                rel[e * N + i] = r
                any_nan = any_nan or np.isnan(r)
        tilt = np.nan
        if N > 0 and not any_nan:  # (np.median is NaN where a value is)
            tilt = median_in_place(rel)
        if not np.isfinite(tilt):
            tilt = 0.0
        for w in range(W):
            scale[w] = 1.0 / (1.0 + tilt * (w - (W - 1) / 2.0))
        # the plateaus' levels: their means over the end pixels, then over neighbouring scan lines
        for e in range(2):
            o = 0 if e == 0 else W - pk
            for i in range(N):
                sm = 0.0
                for j in range(pk):
                    sm += v[g, i, o + j] * scale[o + j]
                ends[e, i] = sm / pk
        lo = _running_mean_nearest(ends[0], size)
        hi = _running_mean_nearest(ends[1], size)
        for i in range(N):
            span = hi[i] - lo[i]
            good[g, i] = abs(span) > 1e-9
            den = span if good[g, i] else 1.0
            for k in range(L):
                # 0 on the first end, 1 on the last: any polarity
                row[k] = (v[g, i, pk + k] * scale[pk + k] - lo[i]) / den
                n[g, i, k] = row[k]
            # area estimate, index units: (L - 1) minus the trapezoid area of the normalised profile
            centre[g, i] = (L - 1) - (pairwise_sum(row, 0, L) - 0.5 * (row[0] + row[L - 1]))
    return n, centre, good


def _paired_warm_up(k) -> None:
    k(np.full((2, 5, 6), 0.5), np.full((2, 5), 2.5), np.ones((2, 5), np.bool_), np.zeros(5, np.int64), 1)


@kernel(_paired_warm_up)
def _paired_asymmetry(n, centre, good, blocks, nb):
    """:func:`_asymmetry`'s measure over the normalised profiles (:func:`_normalised_profiles`) of each
    block (``blocks`` (N,) < ``nb``): (G, nb)."""
    G, N, L = n.shape
    B = 4 * (L - 1)  # |d| * 8 never exceeds it inside the reach
    nbins = 2 * B + 1
    out = np.empty((G, nb))
    acc = np.zeros((nb, nbins))
    cnt = np.zeros((nb, nbins), dtype=np.int64)
    rows_ok = np.zeros(nb)
    rr = np.empty(B)
    reach = (L - 1) / 2.0 - 1.0
    for g in range(G):
        acc[:] = 0.0
        cnt[:] = 0
        rows_ok[:] = 0.0
        for i in range(N):
            if not good[g, i]:
                continue
            b = blocks[i]
            rows_ok[b] += 1.0
            for k in range(L):
                d = k - centre[g, i]
                if abs(d) <= reach:
                    at = int(np.rint(d * 8)) + B
                    acc[b, at] += n[g, i, k]
                    cnt[b, at] += 1
        for b in range(nb):
            m = 0
            for k in range(B):
                cp, cn = cnt[b, B + 1 + k], cnt[b, B - 1 - k]  # bins at +d and -d, d = (k + 1) / 8
                if cp > 0 and cn > 0:
                    r = acc[b, B + 1 + k] / cp + acc[b, B - 1 - k] / cn - 1.0
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
    """:func:`_asymmetry`'s measure where every profile samples the transition at one pixel phase.

    There the pixels at ``+d`` from the centre have no partners at ``-d``: the profiles of each block
    (normalised ``n`` (G, N, L), their area centres ``centre`` (G, N), ``good`` (G, N)) are averaged
    (their phases lie within a fraction of a pixel: the mean is the transition smoothed by an even spread,
    still symmetric in linear light) and the mean transition is read at ``centre +- d`` by a cubic spline
    through its pixels. The spline is exact enough only where the blur makes the transition smooth on the
    pixel scale (optical sigma 1 px and more: errors of a few per cent in the exponent on synthetic steps,
    up to a fifth at high exponents, where the measure is flat), so its readings carry a floor
    (``RESPONSE_ONE_PHASE_SIGMA``). A cubic spline and not a local kernel: on the same synthetic steps
    (exponents 1.0-2.2, blur 1.0-1.4 px, six phases) Keys' cubic convolution and a Lanczos-3 window
    misread the exponent by up to 0.6 and 2.0, the spline by up to 0.06 below 1.6 and 0.5 at 2.2. Same
    shapes and NaN rules as :func:`_asymmetry`.
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


def _vertex(grid: np.ndarray, a: np.ndarray) -> float:
    """The minimum of ``a`` over the increasing ``grid``: the vertex of the parabola (in ``log g``) through
    the least value and its two neighbours; the least grid value at an end or beside a NaN."""
    i = int(_least_index(a))
    if i < 0:
        return float("nan")
    if i == 0 or i == grid.size - 1 or not (math.isfinite(a[i - 1]) and math.isfinite(a[i + 1])):
        return float(grid[i])
    # the parabola through three points in closed form (np.polyfit's least squares on three points is the
    # same curve at ~50x the cost; this runs ~40 times per line)
    x0, x1, x2 = (math.log(float(g)) for g in grid[i - 1 : i + 2])
    y0, y1, y2 = float(a[i - 1]), float(a[i]), float(a[i + 1])
    s0, s2 = (y0 - y1) / (x0 - x1), (y2 - y1) / (x2 - x1)
    curv = (s2 - s0) / (x2 - x0)
    if curv <= 0:
        return float(grid[i])
    # slope at x1 of the parabola: s0 + curv (x1 - x0), so its vertex lies that over 2 curv before x1
    return float(math.exp(min(max(x1 - (s0 + curv * (x1 - x0)) / (2.0 * curv), x0), x2)))


def _least_asymmetric(t: _Transitions, grid: np.ndarray) -> tuple[float, tuple[float, ...]]:
    """The exponent of least :func:`_asymmetry`: the best of ``grid``, then of a grid four times finer
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
    a = _asymmetry(t, grid)
    i = int(_least_index(a))
    if i < 0:
        return float("nan"), ()

    def refined(i: int) -> float:
        fine = np.geomspace(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)], 9)
        return _vertex(fine, _asymmetry(t, fine))

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
    t: _Transitions, grid: np.ndarray, blocks: np.ndarray, n_blocks: int
) -> np.ndarray:
    """:func:`_least_asymmetric` on each block of profiles (NaN where a block has no minimum)."""
    a = _asymmetry(t, grid, blocks, n_blocks)  # (G, n_blocks)
    coarse = [_vertex(grid, a[:, k]) for k in range(n_blocks)]  # (NaN where a block has no finite value)
    found = [g for g in coarse if math.isfinite(g)]
    if not found:
        return np.full(n_blocks, np.nan)
    step = grid[1] / grid[0]
    fine = np.geomspace(min(found) / step, max(found) * step, 21)
    af = _asymmetry(t, fine, blocks, n_blocks)
    return np.array(
        [_vertex(fine, af[:, k]) if math.isfinite(coarse[k]) else math.nan for k in range(n_blocks)]
    )


def combine_responses(
    lines: dict[str, LineResponse], claimed: float, claimed_sigma: float = 0.0
) -> ResponseFit | None:
    """One response for the image: the lines' exponents weighted by their inverse variances.

    ``claimed`` (``claimed_sigma``: its 1-sigma where it was measured, else 0) is the cell's exponent.

    Its standard error is widened by the lines' disagreement beyond their own errors (Birge ratio), so
    two edges that disagree (texture, shading) do not make a confident camera response, and is no smaller
    than the part of the lines' errors that they share (:attr:`LineResponse.shared_sigma`).

    Where every line admits other exponents too (:attr:`LineResponse.alternatives`), the image's reading
    is ambiguous: the alternatives are kept (:attr:`ResponseFit.alternatives`; one line without them
    decides), and where the cell's exponent was measured, the reading nearest to it is the image's
    (the calibration's measurement tells them apart).
    """
    ok = {k: v for k, v in lines.items() if math.isfinite(v.gamma) and math.isfinite(v.sigma) and v.sigma > 0}
    if not ok:
        return None
    g = np.array([v.gamma for v in ok.values()])
    s = np.array([v.sigma for v in ok.values()])
    w = 1.0 / s**2
    mean = float(np.sum(w * g) / np.sum(w))
    se = float(1.0 / math.sqrt(np.sum(w)))
    if g.size > 1:
        chi2 = float(np.sum(w * (g - mean) ** 2)) / (g.size - 1)
        se *= math.sqrt(max(chi2, 1.0))
    # what every line shares does not average down (two edges square to the camera, both read 1.26 +-
    # 0.25 for a 1.43 camera through the same lens, had pooled to +-0.18)
    se = max(se, float(np.sum(w * np.array([v.shared_sigma for v in ok.values()])) / np.sum(w)))
    alternatives: tuple[float, ...] = ()
    if all(v.alternatives for v in ok.values()):
        alternatives = tuple(sorted({round(a, 4) for v in ok.values() for a in v.alternatives}))
        if claimed_sigma > 0:
            readings = (mean, *alternatives)
            nearest = min(readings, key=lambda r: abs(math.log(r / claimed)))
            alternatives = tuple(r for r in readings if r != nearest)
            mean = nearest
    return ResponseFit(
        mean, se, claimed, tuple(ok), claimed_sigma, alternatives, any(v.one_phase for v in ok.values())
    )


def edge_shift_px(
    lo: float, hi: float, camera_gamma: float, used_gamma: float, blur_px: float, half: int
) -> float:
    """Where the area estimator puts a plain step read with ``used_gamma`` when the camera's is another, px.

    The step model: light ``a + (b - a) Phi(x / s)`` between the plateaus' light ``a = lo^camera_gamma``
    and ``b = hi^camera_gamma`` (``lo``, ``hi``: their raw grey levels, full scale 1), ``s`` the optical
    blur with the pixel's width in quadrature, recorded as ``light^(1 / camera_gamma)``, linearised with
    ``used_gamma`` and located by its area over the window ``[-half - 1/2, half + 1/2]``. Returns the
    estimate minus the true edge, along the dark-to-bright direction (0 when the two exponents agree).
    :func:`edge_shifts_px` gives it for several camera exponents at once.
    """
    return float(edge_shifts_px(lo, hi, np.array([camera_gamma], float), used_gamma, blur_px, half)[0])


def edge_shifts_px(
    lo: float, hi: float, camera_gammas: np.ndarray, used_gamma: float, blur_px: float, half: int
) -> np.ndarray:
    """:func:`edge_shift_px` for each of the camera exponents ``camera_gammas`` (G,), px (G,): the blurred
    step is made once for all of them."""
    camera_gammas = np.asarray(camera_gammas, float)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo >= 0.0):
        return np.full(camera_gammas.shape, np.nan)
    s = math.sqrt(max(blur_px, 0.0) ** 2 + 1.0 / 12.0)
    w = half + 0.5
    phi, dx = _blurred_step(w, s)
    g = camera_gammas[:, None]
    a, b = lo**g, hi**g
    raw = (a + (b - a) * phi) ** (1.0 / g)
    n = (raw**used_gamma - lo**used_gamma) / (hi**used_gamma - lo**used_gamma)
    # area estimator: the edge where a sharp step would hold the same area (np.trapezoid's sum, spelt out:
    # its steps dx are the window's, made once)
    return w - (dx * (n[:, 1:] + n[:, :-1]) / 2.0).sum(-1)


@functools.lru_cache(maxsize=64)
def _blurred_step(w: float, s: float) -> tuple[np.ndarray, np.ndarray]:
    """A unit step blurred by ``s`` px over ``[-w, w]``: ``Phi(x / s)`` at 401 samples ``x``, and ``diff(x)``.

    The lines of one image share their window and blur, so this is made once per image, not per line and
    exponent (read-only arrays: the cache hands the same ones out). (401 samples: within 4e-6 px of 2001
    over plateaus 0.05-0.9, blur 0-2 px, windows 3-12 px, and a fifth of the time.)
    """
    x = np.linspace(-w, w, 401)
    phi, dx = ndtr(x / s), np.diff(x)
    phi.flags.writeable = dx.flags.writeable = False
    return phi, dx


def plateau_levels(
    plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int
) -> tuple[float, float]:
    """The dark and bright plateau's raw grey level just beyond the window (medians, full scale 1)."""
    P = oriented(plane, samples.axis)  # (for rows, the plane's transpose: an F-ordered view, no copy)
    top = 255.0 if plane.dtype == np.uint8 else 65535.0
    lo, hi = _end_pixel_medians(P, samples.scan, samples.along, np.ascontiguousarray(mask, np.bool_), half)
    return lo / top, hi / top


def _end_pixel_medians_warm_up(k) -> None:
    for dtype in (np.uint8, np.uint16):
        P = np.zeros((12, 12), dtype)
        for Q in (P, P.T):
            k(Q, np.arange(5), np.full(5, 6.0), np.ones(5, np.bool_), 2)


@kernel(_end_pixel_medians_warm_up)
def _end_pixel_medians(P, scan, along, mask, half):
    """The medians of the pixels just beyond the window ``round(along) +- half`` on each scan line of ``P``
    (``P[along, scan]``) with ``mask`` (lines whose window leaves the image skipped), the smaller first;
    NaN with fewer than 3 lines (np.median's values, compiled)."""
    n = scan.size
    ends = np.empty((2, n))
    m = 0
    for i in range(n):
        if not mask[i]:
            continue
        c0 = int(np.rint(along[i]))
        a, b = c0 - half - 1, c0 + half + 1
        if a >= 0 and b < P.shape[0]:
            ends[0, m] = P[a, scan[i]]
            ends[1, m] = P[b, scan[i]]
            m += 1
    if m < 3:
        return np.nan, np.nan
    a, b = median_in_place(ends[0, :m]), median_in_place(ends[1, :m])
    return min(a, b), max(a, b)


def fit_board_response(
    plane: np.ndarray,
    corners_px: np.ndarray,
    cols: int,
    rows: int,
    used_gamma: float = 1.0,
    blur_px: float = 1.5,
) -> LineResponse | None:
    """The camera response measured on a checkerboard's square edges (the calibration images).

    A printed board has hundreds of plain black-white edges at every pixel phase and angle: the same
    measurement as :func:`fit_line_response` on a door's plain edge (the transition of a step blurred by an
    even spread is symmetric in linear light), pooled over the board. Each edge between two neighbouring
    inner corners is read on the scan lines across its middle 40 % (the corners' X-junctions and the
    square's other edges stay out of the window), placed by the area estimator, and its raw profile turned
    to run dark to bright; the exponent's standard error is the scatter over blocks of whole edges.

    Parameters
    ----------
    plane : ndarray (H, W)
        The raw grey image (uint8 or uint16), as the camera wrote it.
    corners_px : ndarray (cols * rows, 2)
        Inner corners in grid order (row by row, ``cols`` per row), px.
    cols, rows : int
        Inner corners per row and per column.
    used_gamma : float
        The exponent the edges are placed with (its skew is reported).
    blur_px : float
        The largest optical blur expected (Gaussian sigma, px): sizes the window (3 sigmas and the plateaus
        each side); edges of squares too small for it are left out.

    Returns
    -------
    LineResponse or None
        None with too few usable edges (squares under about 30 px at 1.5 px of blur, or too few in view).
    """
    corners = np.asarray(corners_px, float).reshape(rows, cols, 2)
    top = 255.0 if plane.dtype == np.uint8 else 65535.0
    lut = linearizing_lut(plane.dtype, used_gamma)
    want = int(math.ceil(RESPONSE_WINDOW_BLURS * max(blur_px, 0.0) + 1.5))
    raws, offsets = [], []
    pairs = [(corners[r, c], corners[r, c + 1]) for r in range(rows) for c in range(cols - 1)] + [
        (corners[r, c], corners[r + 1, c]) for r in range(rows - 1) for c in range(cols)
    ]
    for p0, p1 in pairs:
        d = p1 - p0
        length = float(np.hypot(*d))
        # Scan lines across the edge's middle 40 %: a profile there meets the square's other edges no nearer
        # than 0.42 of a square (at 45 deg; farther at other angles), so a window (plateaus included) of
        # 0.3 of a square each side stays clear of them and of their blur.
        half = want
        if not (np.all(np.isfinite(d)) and half + RESPONSE_PLATEAU_PX <= 0.3 * length):
            continue  # squares too small for the transition and its plateaus
        axis: Axis = "col" if abs(d[0]) >= abs(d[1]) else "row"  # profiles across the edge
        i_s, i_a = (0, 1) if axis == "col" else (1, 0)
        s0, s1 = sorted((p0[i_s] + 0.3 * d[i_s], p0[i_s] + 0.7 * d[i_s]))
        scan = np.arange(int(math.ceil(s0)), int(math.floor(s1)) + 1)
        if scan.size < 4:
            continue
        centre = p0[i_a] + (scan - p0[i_s]) * (d[i_a] / d[i_s])
        smp = subpixel_edges(plane, axis, scan, centre, half, RESPONSE_PLATEAU_PX, lut=lut)
        ok = smp.valid & np.isfinite(smp.along) & (np.abs(smp.along - centre) < 2.0)
        if int(ok.sum()) < 4:
            continue
        H = half + RESPONSE_PLATEAU_PX
        e = smp.along[ok]
        c0 = np.round(e).astype(int)
        vals, inside = gather_profiles(oriented(plane, axis), scan[ok], c0 - H, 2 * H + 1)
        keep = inside.all(axis=1)
        raw = vals[keep].astype(np.float64) / top
        off = (c0 - H - e)[keep].astype(np.float64)
        if raw.shape[0] < 4:
            continue
        if raw[:, -RESPONSE_PLATEAU_PX:].mean() < raw[:, :RESPONSE_PLATEAU_PX].mean():
            raw, off = raw[:, ::-1], -off - 2 * H  # dark to bright, as every other edge
        raws.append(raw)
        offsets.append(off)
    if len(raws) < 3 * RESPONSE_SKEW_BLOCKS:
        return None
    raw = np.concatenate(raws)
    t = _Transitions(raw, np.concatenate(offsets), dithered=_dithered(raw, top))
    # blocks of whole edges (neighbouring edges share the board's print and light, far ones need not)
    n_blocks = 2 * RESPONSE_SKEW_BLOCKS
    edge_block = np.array_split(np.arange(len(raws)), n_blocks)
    blocks = np.concatenate(
        [np.full(raws[i].shape[0], k) for k, idx in enumerate(edge_block) for i in idx]
    ).astype(np.int64)
    found = _exponent_with_scatter(t, blocks, n_blocks)
    if found is None:
        return None
    g, se, alternatives = found
    lo, hi = (float(v) for v in np.median(t.raw[:, [0, -1]], axis=0))
    return LineResponse(g, se, lo, hi, _skew(t, slice(None), used_gamma), alternatives=alternatives)


#: fewest board images whose responses :func:`board_response` pools (their scatter is the doubt)
BOARD_RESPONSE_MIN_IMAGES = 5


@dataclass(frozen=True)
class BoardResponse:
    """The camera response measured on the calibration photographs (:func:`board_response`).

    Attributes
    ----------
    gamma, sigma : float
        The exponent (``grey = light ** (1 / gamma)``), the median of the images' own, and its 1-sigma from
        their scatter: on real photographs one image's own standard error understates it several times
        (JPEG, in-camera sharpening and print texture skew single edges: the OpenCV sample images scatter
        from 0.85 to 3.36), so the images are taken as independent measurements and nothing else.
    per_image : tuple of float
        Each usable image's exponent.
    """

    gamma: float
    sigma: float
    per_image: tuple[float, ...]

    @property
    def unmeasured_factor(self) -> float:
        """``locate.response_unmeasured_factor`` that this measurement allows (its 2-sigma range as a factor)."""
        from doorloc.cell import measured_response_factor  # (the cell file's rule, kept in one place)

        return measured_response_factor(self.gamma, self.sigma)


def board_response(
    views: list[tuple[np.ndarray, np.ndarray]], cols: int, rows: int, blur_px: float = 1.5
) -> BoardResponse | None:
    """The camera response from photographs of a checkerboard, pooled robustly over the images.

    ``views``: (raw grey image, all ``cols * rows`` inner corners in the board's row-major order) per
    photograph. Each image gives its exponent (:func:`fit_board_response`); the answer is their median and
    its standard error from their median absolute deviation (``1.2533 * 1.4826 * MAD / sqrt(n)``, the
    median's efficiency), at least the images' own standard error over ``sqrt(n)``. None with fewer than
    ``BOARD_RESPONSE_MIN_IMAGES`` usable images.
    """
    fits = [fit_board_response(img, c, cols, rows, blur_px=blur_px) for img, c in views]
    ok = [f for f in fits if f is not None and RESPONSE_GAMMA_RANGE[0] < f.gamma < RESPONSE_GAMMA_RANGE[1]]
    if len(ok) < BOARD_RESPONSE_MIN_IMAGES:
        return None
    g = np.array([f.gamma for f in ok])
    med = float(np.median(g))
    n = g.size
    spread = 1.2533 * 1.4826 * float(np.median(np.abs(g - med))) / math.sqrt(n)
    own = float(np.median([f.sigma for f in ok])) / math.sqrt(n)
    return BoardResponse(med, max(spread, own, RESPONSE_SIGMA_FLOOR), tuple(float(x) for x in g))
