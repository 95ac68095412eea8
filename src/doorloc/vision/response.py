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
error (:mod:`doorloc.vision.response_asymmetry`).

:mod:`doorloc.vision.board_response` measures the same on the calibration photographs' chessboard edges
(``doorloc calibrate`` stores it with the camera model): a camera's response once, where hundreds of plain
edges at every phase are in view, so that doors whose edges cannot show it (arrises, a sharp door square to
the camera) need not doubt it by the full range of cameras' exponents.

What a response error does to the edge follows from the step model, not from a tuned factor:
:func:`edge_shift_px` is where the area estimator puts a Gaussian-blurred step between the line's two
measured plateaus, linearised with one exponent when the camera's is another. Locate uses it for the response
term of the uncertainty budget (``response_sigma_mm`` per line): where the fitted response differs from the
cell's beyond ``RESPONSE_ABSORB_SIGMAS`` standard errors on two edges or more (the combination of the image's
and, where the cell's exponent was measured, its ``camera.response_gamma_sigma``), and the lines read over a
window 3 px wider confirm it (texture or shading beside an edge skews its transition as a response does, but
not alike over both windows: :mod:`doorloc.vision.response_check`) and no line's transition overshoots
both its plateaus (a camera that sharpens: :mod:`doorloc.vision.response_overshoot`), locate measures again
with the fitted one (the error is absorbed) and the doubt left is the shift that the exponent's standard error makes; otherwise
the doubt is the shift between the cell's exponent and the fitted one beyond twice that (a right cell keeps
its small sigma), except for a reading between the pixels (a door square to the camera), which is combined
with the cell's exponent as known within ``locate.response_unmeasured_factor``
(:meth:`ResponseFit.with_unmeasured_claim`). Where every plain edge admits a second exponent about as well
(the asymmetry is not monotone in the exponent: :func:`least_asymmetric`), the image cannot tell the camera's:
nothing is absorbed and the doubt is the largest shift of the readings.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.special import ndtr

from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.jit import kernel, median_in_place
from doorloc.vision.response_asymmetry import (
    RESPONSE_GAMMA_RANGE,
    RESPONSE_PLATEAU_PX,
    Transitions,
    dithered,
    exponent_with_scatter,
    transition_skew_px,
)
from doorloc.vision.sampling import gather_profiles, oriented

__all__ = [
    "RESPONSE_ABSORB_SIGMAS",
    "RESPONSE_DECIDED_SIGMAS",
    "RESPONSE_GAMMA_RANGE",
    "RESPONSE_ONE_PHASE_MIN_BLUR_PX",
    "RESPONSE_PLAUSIBLE",
    "RESPONSE_PLAUSIBLE_SIGMAS",
    "RESPONSE_SKEW_BLOCKS",
    "LineResponse",
    "ResponseFit",
    "combine_responses",
    "a_cameras_reading",
    "at_one_phase",
    "edge_shift_px",
    "edge_shifts_px",
    "fit_line_response",
    "line_transitions",
    "plateau_levels",
]

#: contiguous blocks along the line over which the skew is measured again, for its standard error
RESPONSE_SKEW_BLOCKS = 8
#: half width of the window the transition is read over, in blur sigmas (plus 1.5 px)
RESPONSE_WINDOW_BLURS = 3.0
#: profiles the fit uses at most (every k-th along the line)
RESPONSE_MAX_PROFILES = 320
#: the fitted response replaces the cell's when it differs by more than this many standard errors
RESPONSE_ABSORB_SIGMAS = 4.0
#: an edge at one pixel phase (along a pixel row or column) is read between its pixels by interpolation
#: only from this optical blur on (Gaussian sigma, px; sharper transitions are not smooth on the pixel
#: scale), and its exponent's 1-sigma is at least this fraction of it (:mod:`doorloc.vision.response_asymmetry`):
#: on rendered doors square to the camera (wide random lighting and albedos, blur 1.1-1.7 px, exponents
#: 1.0-2.4) the readings were 23 % RMS off, and their pulls 1.0 RMS with this floor (1.7 with 0.1)
RESPONSE_ONE_PHASE_MIN_BLUR_PX = 1.0
RESPONSE_ONE_PHASE_SIGMA = 0.2
#: ... and at least this exponent over the log of the ratio of its plateaus' raw levels: the asymmetry an
#: exponent off by a fraction makes grows with the edge's contrast in light (the log of its plateaus' ratio),
#: so what every scan line of one phase shares (the interpolation, JPEG's quantisation of the transition,
#: grain stripes along the edge), which the blocks' scatter does not see, misreads a faint edge's exponent
#: the more. On 104 readings inside the range read, of square doors (exponents 1.0-2.4 stated; 74 clean,
#: albedos 0.03-0.9, and 30 under the grain set's grain, vignetting, gradients and JPEG 88), the pulls were
#: 1.79 RMS with the floor above alone (faint edges, log ratio under 0.5: 2.47; the grain set's 2.75), and
#: with this 0.90 (0.83-0.95 at every contrast, 0.86 clean and 0.99 under the grain set's photometry)
RESPONSE_ONE_PHASE_CONTRAST = 0.3
#: ... and, as the blur falls towards a pixel, at least this fraction of it times (1 px / blur)^3: the
#: spline between one phase's samples assumes a Gaussian spread, and the same steps blurred by OpenCV's
#: sampled Gaussian kernel instead of a continuous one read up to 47 / 27 / 15 % off at 1.0 / 1.2 /
#: 1.5 px, as the pixel phase went (a lens's spread is no Gaussian either)
RESPONSE_ONE_PHASE_PSF = 0.5
#: the exponents a camera's response has (a linear sensor 1.0, video and sRGB about 2.2-2.4): only a fit
#: inside is absorbed
RESPONSE_PLAUSIBLE = (0.8, 3.0)
#: a reading lies beyond RESPONSE_PLAUSIBLE where it misses it by this many of its own sigmas
#: (:func:`a_cameras_reading`)
RESPONSE_PLAUSIBLE_SIGMAS = 2.0
#: a line that admits other exponents is read at the one nearest the unambiguous lines' only where its first
#: reading lies more than this many of their joint sigmas from theirs (:func:`_decided_by_unambiguous`):
#: within it, both readings are the same camera's as far as the lines can tell (on the sharp doors of
#: ``bench_arris_range.py --seed 7000``, a first reading of 1.42 +- 0.24 beside an unambiguous 1.72 +-
#: 0.20, for a 1.57 camera, would have moved to its alternative of 1.83)
RESPONSE_DECIDED_SIGMAS = 3.0


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
        Read at one pixel phase, between the pixels by interpolation (:func:`asymmetry`).
    alternatives : tuple of float
        Other exponents that make the transition about as symmetric (:func:`least_asymmetric`): the edge
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
    def departs(self) -> bool:
        """Whether it lies beyond ``RESPONSE_ABSORB_SIGMAS`` joint sigmas of the claim, whether or not a
        camera has its exponent and on however many edges (and the edges read no other exponent about as
        well, one of which may be the claim): read again with an exponent just absorbed as the claim, edges
        that read yet another are no measurement of the camera
        (:func:`doorloc.vision.response_check.check_response`). Where the claim was not measured, every
        reading that is to be absorbed departs."""
        return not self.alternatives and self.disagreement > RESPONSE_ABSORB_SIGMAS

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
        return abs(g - self.claimed) > RESPONSE_ABSORB_SIGMAS * se or self.departs


def a_cameras_reading(gamma: float, sigma: float) -> bool:
    """Whether an exponent read as ``gamma`` +- ``sigma`` may be a camera's: within ``RESPONSE_PLAUSIBLE``
    by ``RESPONSE_PLAUSIBLE_SIGMAS`` of its sigmas. Beyond, the reading is of texture or shading, whatever
    its sigma says (a weak reading in the doubts, a line's reading over a wider window)."""
    lo, hi = RESPONSE_PLAUSIBLE
    reach = RESPONSE_PLAUSIBLE_SIGMAS * sigma
    return lo - reach <= gamma <= hi + reach


def at_one_phase(scan_px: np.ndarray, along_px: np.ndarray) -> bool:
    """Whether an edge whose points lie at ``along_px`` (N,) on the scan lines ``scan_px`` (N,) misses a
    quarter of the pixel phases (an edge along a pixel row or column), where the mean transition cannot be
    read at every offset.

    The phases are the edge's own, a quadratic through its points along the line, not each point's: a
    point's noise (0.05-0.1 px at one grey level of noise on a step of 40) scatters a few points of an
    edge along a pixel row into every quarter. Counted point by point, such an edge (a linear camera, a
    door 0.02 deg from square, blur 1.1 px) was read between its few phases as if at many, 2.2-2.3 +- 0.13
    in three of four noise draws: the cell's exponent was replaced by it and the answer was 5-8 sigma off.

    Examples
    --------
    >>> s = np.arange(300.0)
    >>> at_one_phase(s, 10.3 + 0.0003 * s + np.where(s % 7 == 0, 0.4, 0.0))
    True
    >>> at_one_phase(s, 10.3 + 0.01 * s)
    False
    """
    scan = np.asarray(scan_px, np.float64)
    along = np.asarray(along_px, np.float64)
    ok = np.isfinite(scan) & np.isfinite(along)
    scan, along = scan[ok], along[ok]
    if scan.size < 3 or not scan.max() > scan.min():
        return np.unique(np.floor((along % 1.0) * 4.0)).size < 4
    # The least-squares quadratic by its normal equations, over the scan lines scaled to [-1, 1] (well
    # posed), and the quarters its values span between its ends and its vertex: this runs on every plain
    # line of every frame, twice, where np.polyfit and counting each point's quarter took 140 us a line.
    lo_scan, hi_scan = scan.min(), scan.max()
    u = (2.0 * scan - (lo_scan + hi_scan)) / (hi_scan - lo_scan)
    u2 = u * u
    m1, m2, m3, m4 = u.sum(), u2.sum(), u2 @ u, u2 @ u2
    normal = np.array([[u.size, m1, m2], [m1, m2, m3], [m2, m3, m4]])
    c0, c1, c2 = np.linalg.solve(normal, np.array([along.sum(), u @ along, u2 @ along]))
    at = [-1.0, 1.0] + ([-c1 / (2.0 * c2)] if c2 != 0.0 and abs(c1) < 2.0 * abs(c2) else [])
    values = [c0 + c1 * v + c2 * v * v for v in at]
    return math.floor(4.0 * max(values)) - math.floor(4.0 * min(values)) < 3


def _transitions(plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int) -> Transitions | None:
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
    offset = (c0[ok] - half - e[ok])[order].astype(np.float64)
    one_phase = at_one_phase(samples.scan[m][ok], e[ok])
    return Transitions(raw, offset, one_phase=one_phase, dithered=dithered(raw, top), top=top)


def fit_line_response(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    used_gamma: float,
    blur_px: float = 0.0,
    wider_px: int = 0,
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
    wider_px : int
        Pixels added to the window on each side (a reading of a clean step does not depend on them).

    Returns
    -------
    LineResponse or None
        None where too few profiles are usable, an edge at one pixel phase is too sharp to be read
        between its pixels or its plateaus do not differ, or the asymmetry has no least over
        ``RESPONSE_GAMMA_RANGE`` (a least at the range's end is a reading:
        :func:`doorloc.vision.response_asymmetry.least_asymmetric`).
    """
    # The window holds the whole transition (3 blur sigmas each side) and plateaus at both ends.
    read = line_transitions(plane, samples, mask, half, blur_px, wider_px)
    if read is None:
        return None
    t, wide = read
    one_phase = t.one_phase
    # Read between the pixels only where the optical blur itself makes the transition smooth (a line's
    # transition width is inflated by noise and texture: 2.6 px measured on a door blurred by 0.67 px,
    # whose two edges then read 0.63 and 3.4 for a linear camera).
    one_phase_blur = _one_phase_blur(t, used_gamma) if one_phase else float("nan")
    if one_phase and not one_phase_blur >= RESPONSE_ONE_PHASE_MIN_BLUR_PX:
        return None
    t = t.at_most(RESPONSE_MAX_PROFILES)
    n_blocks = min(RESPONSE_SKEW_BLOCKS, t.raw.shape[0] // 12)
    if n_blocks < 3:
        return None
    # the standard error from the exponent's scatter over contiguous blocks of scan lines (texture and
    # shading beside the edge change slowly along it)
    blocks = np.repeat(
        np.arange(n_blocks), [len(b) for b in np.array_split(np.arange(t.raw.shape[0]), n_blocks)]
    )
    found = exponent_with_scatter(t, blocks, n_blocks)
    if found is None:
        return None
    g, se, alternatives = found
    # an exponent no camera has is no second reading (the primary one is kept whatever it is: the
    # doubt takes the nearest plausible one)
    alternatives = tuple(a for a in alternatives if RESPONSE_PLAUSIBLE[0] <= a <= RESPONSE_PLAUSIBLE[1])
    lo, hi = plateau_levels(plane, samples, mask & samples.valid, wide)
    shared = _one_phase_shared_sigma(g, one_phase_blur, lo, hi) if one_phase else 0.0
    if not math.isfinite(shared):
        return None
    se = math.hypot(se, shared)
    return LineResponse(
        g,
        se,
        lo,
        hi,
        transition_skew_px(t, slice(None), used_gamma),
        one_phase,
        alternatives,
        shared_sigma=shared,
    )


def _one_phase_shared_sigma(g: float, blur_px: float, lo: float, hi: float) -> float:
    """The 1-sigma (exponent) of a reading ``g`` at one pixel phase that its blocks share (one phase: one
    spline error, one JPEG quantisation of the transition) and the image's other edges too (one lens): the
    floors ``RESPONSE_ONE_PHASE_SIGMA``, ``RESPONSE_ONE_PHASE_PSF`` (at the transition's blur, px) and
    ``RESPONSE_ONE_PHASE_CONTRAST`` (between the plateaus' raw levels ``lo`` and ``hi``); infinite where
    the plateaus do not differ."""
    contrast = abs(math.log(hi / lo)) if lo > 0 and hi > 0 else 0.0
    if not contrast > 0:
        return math.inf
    return max(
        g * RESPONSE_ONE_PHASE_SIGMA,
        g * RESPONSE_ONE_PHASE_PSF / blur_px**3,
        RESPONSE_ONE_PHASE_CONTRAST / contrast,
    )


def line_transitions(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    blur_px: float = 0.0,
    wider_px: int = 0,
) -> tuple[Transitions, int] | None:
    """The profiles across one plain edge that :func:`fit_line_response` reads (its arguments), and the half
    width of their window (px; the plateaus lie outside it): the whole transition (``RESPONSE_WINDOW_BLURS``
    blur sigmas each side and 1.5 px) and at least ``half``, ``wider_px`` more each side. None where fewer
    than 10 profiles lie whole in the image."""
    wide = max(half, int(math.ceil(RESPONSE_WINDOW_BLURS * max(blur_px, 0.0) + 1.5))) + wider_px
    t = _transitions(plane, samples, mask, wide + RESPONSE_PLATEAU_PX)
    return None if t is None else (t, wide)


def _one_phase_blur(t: Transitions, used_gamma: float) -> float:
    """The optical blur (Gaussian sigma, px) of a transition sampled at one pixel phase, NaN if unreadable.

    The profiles linearised with ``used_gamma``, normalised by their plateaus and averaged (the noise
    and the texture along the edge average out), differ from pixel to pixel by the blur's line spread
    integrated over two pixels (a Gaussian of variance ``sigma^2 + 1/6``): the curvature of its
    logarithm at the peak's three pixels gives it at any phase (exact for a Gaussian blur; the plateaus'
    slopes, which inflate a width measured over the window, do not reach the peak). A step-model fit
    (:func:`doorloc.vision.step_blur.step_blur`) gives the same and cost ~6 ms per line.
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


def combine_responses(
    lines: dict[str, LineResponse], claimed: float, claimed_sigma: float = 0.0
) -> ResponseFit | None:
    """One response for the image: the lines' exponents weighted by their inverse variances.

    ``claimed`` (``claimed_sigma``: its 1-sigma where it was measured, else 0) is the cell's exponent.

    Its standard error is widened by the lines' disagreement beyond their own errors (Birge ratio), so
    two edges that disagree (texture, shading) do not make a confident camera response, and is no smaller
    than the part of the lines' errors that they share (:attr:`LineResponse.shared_sigma`).

    Where every line admits other exponents too (:attr:`LineResponse.alternatives`), the image's reading
    is ambiguous: the alternatives are kept (:attr:`ResponseFit.alternatives`), and where the cell's
    exponent was measured, the reading nearest to it is the image's (the calibration's measurement tells
    them apart). Where some line admits none, those lines decide: an ambiguous line whose first reading
    disagrees with theirs is read at its exponent nearest theirs (:func:`_decided_by_unambiguous`).
    """
    ok = {k: v for k, v in lines.items() if math.isfinite(v.gamma) and math.isfinite(v.sigma) and v.sigma > 0}
    if not ok:
        return None
    ok = _decided_by_unambiguous(ok)
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
        # one camera makes every edge: an exponent a line neither reads nor admits is no camera's
        admitted = [a for v in ok.values() for a in v.alternatives if all(_admits(u, a) for u in ok.values())]
        alternatives = tuple(sorted({round(a, 4) for a in admitted}))
        if claimed_sigma > 0:
            readings = (mean, *alternatives)
            nearest = min(readings, key=lambda r: abs(math.log(r / claimed)))
            alternatives = tuple(r for r in readings if r != nearest)
            mean = nearest
    return ResponseFit(
        mean, se, claimed, tuple(ok), claimed_sigma, alternatives, any(v.one_phase for v in ok.values())
    )


def _admits(line: LineResponse, gamma: float) -> bool:
    """Whether ``line`` admits the exponent ``gamma``: it lies within ``RESPONSE_DECIDED_SIGMAS`` of the
    line's sigmas of its reading or of one of its alternatives (the line's sigma the scale of each)."""
    reach = RESPONSE_DECIDED_SIGMAS * line.sigma
    return any(abs(gamma - g) <= reach for g in (line.gamma, *line.alternatives))


def _decided_by_unambiguous(lines: dict[str, LineResponse]) -> dict[str, LineResponse]:
    """``lines`` with each line that admits other exponents (:attr:`LineResponse.alternatives`) read at the
    one of its exponents nearest (in the log) to the lines that admit none, where there are such lines and
    its first reading lies more than :data:`RESPONSE_DECIDED_SIGMAS` of their joint sigmas from theirs; a
    line so moved to an alternative keeps its own 1-sigma or the alternative's distance from the deciding
    lines' reading, whichever is larger (its scatter was measured about its first reading).

    Why: the asymmetry an edge reads has a second least near 2.5-3 times the camera's exponent
    (:func:`doorloc.vision.response_asymmetry.least_asymmetric`), and a line whose noise put that one
    first, with the camera's as its alternative, outweighed a plain unambiguous line: a 1.37 camera's
    bottom end read 1.38 +- 0.11, its reference arris 3.64 +- 0.02 (alternative 1.35), pooled to 3.57 +-
    0.41, and the plain door was refused for a response doubt of 0.1 mm (``bench_arris_range.py``'s sharp
    set at seed 7000, door 11031)."""
    decided = [v for v in lines.values() if not v.alternatives]
    if not decided or len(decided) == len(lines):
        return lines
    w = np.array([1.0 / v.sigma**2 for v in decided])
    anchor = float(np.exp(np.sum(w * np.log([v.gamma for v in decided])) / np.sum(w)))
    anchor_sigma = float(1.0 / math.sqrt(np.sum(w)))
    out = {}
    for k, v in lines.items():
        nearest = min((v.gamma, *v.alternatives), key=lambda g: abs(math.log(g / anchor)))
        agrees = abs(v.gamma - anchor) <= RESPONSE_DECIDED_SIGMAS * math.hypot(v.sigma, anchor_sigma)
        out[k] = (
            v
            if nearest == v.gamma or not v.alternatives or agrees
            else replace(
                v,
                gamma=nearest,
                sigma=max(v.sigma, abs(nearest - anchor)),
                alternatives=tuple(a for a in (v.gamma, *v.alternatives) if a != nearest),
            )
        )
    return out


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
