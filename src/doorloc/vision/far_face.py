"""The far arris beside a visible far face: a fit of the whole profile's shape.

Beside a visible far face (a thin door shifted towards -X, seen from a camera beyond the far face's plane)
the profile across the far arris holds two blurred steps, the arris and the far face's back edge, a band
of unknown level between them. :func:`subpixel_edges_far_face` fits them (its loops compiled in
:mod:`doorloc.vision.far_face_kernels`); :func:`doorloc.vision.step_blur.step_blur` is the same fit without a
band, the optical blur of a plain step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS
from doorloc.vision.edge_samples import EdgeSamples, ScanWindow
from doorloc.vision.far_band import FarBand, FarFaceFit
from doorloc.vision.far_face_kernels import (
    far_face_gauss_newton,
    far_face_schur,
    far_face_start_costs,
    far_face_sums,
)
from doorloc.vision.sampling import Axis, gather_profiles, median, oriented, smooth_along

__all__ = [
    "BLUR_DOUBT",
    "LEVEL_DOUBT",
    "LEVEL_PRIOR_WEIGHT",
    "subpixel_edges_far_face",
]


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
#: beside an arris strip, two readings of the profiles (the band's, :func:`_band_readings`; the strip's,
#: :func:`_other_strip_reading`) fit alike where the worse one's misfit is at most this many times the
#: better's: the strip model's own error is that large (valid thin doors whose true reading misfit 1.6-1.8
#: times the other's: bench_surfaces.py --sets thin-arris --seed 2611, doors 34 and 38), and such a pair is
#: the image's ambiguity, for the thickness check to weigh
READINGS_ALIKE = 2.0
#: another reading that ends within this of the fit's own (px) is the same reading
READINGS_APART_PX = 1.0


#: the far face's start search ranks its shifts on every START_SUBSET_EVERY-th scan line or fewer (about
#: START_SUBSET_LINES of them), where it has at least START_SUBSET_MIN_LINES, and costs the
#: START_SUBSET_KEEP best on all of them
START_SUBSET_EVERY = 4
START_SUBSET_LINES = 48
START_SUBSET_MIN_LINES = 40
START_SUBSET_KEEP = 4


@dataclass(frozen=True)
class _Profiles:
    """The far-face fit's data on its usable scan lines, in the kernels' index units (mirrored so that the
    hinge face lies at the low indices): the cores between the plateaus ``core`` (N, M), the hinge face's
    level ``A`` and the contrast ``D`` per line, the cores' pixel boundaries ``bounds``, the predicted arris
    ``e0`` and band width ``w0`` there, the band's ``band_slope``, the strip widths ``strip`` (zeros without
    one) and ``has_strip``. Its methods call the kernels of :mod:`doorloc.vision.far_face_kernels`."""

    core: np.ndarray
    A: np.ndarray
    D: np.ndarray
    bounds: np.ndarray
    e0: np.ndarray
    w0: np.ndarray
    band_slope: float
    strip: np.ndarray
    has_strip: bool

    def band_width(self, e: np.ndarray) -> np.ndarray:
        """The band's width with the arrises at ``e``, px (0 where it has vanished)."""
        return np.maximum(self.w0 + self.band_slope * (e - self.e0), 0.0)

    def start_costs(
        self, sigma: float, mu0: float, shifts: np.ndarray, every: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """The cost at each common shift of the predicted arrises and the band level it solves for, on every
        ``every``-th line (a strip at its prior level ``mu0``)."""
        return far_face_start_costs(
            self.core, self.A, self.D, self.bounds, self.e0, self.w0, self.band_slope, sigma, STEP_TAIL_SIGMAS,
            self.strip, self.has_strip, mu0, LEVEL_PRIOR_WEIGHT, shifts, every,
        )  # fmt: skip

    def gauss_newton(
        self,
        prior: _StripPrior,
        e: np.ndarray,
        lam: float,
        sigma: float,
        mu: float,
        fit_blur: bool,
        n_iter: int,
    ) -> tuple[np.ndarray, float, float, float, float]:
        """The Gauss-Newton iterations from ``e, lam, sigma, mu``: the final ones and the cost."""
        return far_face_gauss_newton(
            self.core, self.A, self.D, self.bounds, e, self.w0, self.e0, self.band_slope, sigma,
            STEP_TAIL_SIGMAS, self.strip, self.has_strip, lam, mu, fit_blur, n_iter, LEVEL_PRIOR_WEIGHT,
            prior.pull_mu, prior.mu0, prior.levels_lo, prior.levels_hi,
        )  # fmt: skip

    def sums(self, e: np.ndarray, lam: float, sigma: float, mu: float) -> tuple[np.ndarray, ...]:
        """The Gauss-Newton step's sums at the answer, the blur's column included."""
        return far_face_sums(
            self.core, self.A, self.D, self.bounds, e, self.w0, self.e0, self.band_slope, sigma,
            STEP_TAIL_SIGMAS, self.strip, self.has_strip, lam, mu, True,
        )  # fmt: skip


@dataclass(frozen=True)
class _StripPrior:
    """An arris strip's relative level a priori (``mu0``, ``mu_sd``) and its pull's weight ``pull_mu``, and
    the range ``levels_lo .. levels_hi`` the strip's and the far face's levels are held to (none without a
    strip)."""

    mu0: float = 0.0
    mu_sd: float = 0.0
    pull_mu: float = 0.0
    levels_lo: float = -math.inf
    levels_hi: float = math.inf


def _strip_prior(prof: _Profiles, ends: np.ndarray, strip_radiance: tuple[float, float]) -> _StripPrior:
    """The strip's relative level ``(S - A) / (B - A)`` a priori: its radiance ``strip_radiance`` (mean,
    standard deviation) times the hinge face's (linear light), in units of the contrast; weighed at the
    noise of the profiles' plateaus ``ends``."""
    a_med, d_med = median(prof.A), median(prof.D)
    k = -a_med / d_med if abs(d_med) > 1e-9 * max(abs(a_med), 1e-12) else 0.0
    mu0 = (strip_radiance[0] - 1.0) * -k
    mu_sd = max(strip_radiance[1] * abs(k), 0.05)
    # The strip's and the far face's levels where their radiance is 0-3 times the hinge face's (the
    # same wood: in shadow, or glinting). A far face seen nearly edge-on, a band of a hundredth of a
    # pixel, otherwise took a level of -32 (a spike that moves the step at no cost: effects fixture
    # img_0007, its bottom end then refused as not straight).
    levels_lo, levels_hi = sorted((k, -2.0 * k))
    noise_var = max(median(ends.var(axis=1)), (1e-3 * abs(d_med)) ** 2)
    return _StripPrior(mu0, mu_sd, noise_var / mu_sd**2, levels_lo, levels_hi)


def _start(prof: _Profiles, sigma: float, mu0: float, half: int) -> tuple[np.ndarray, float]:
    """The arrises and band level to start the fit from: the best common shift of all predicted arrises
    (half-pixel steps across the window ``half``).

    A prediction that took the band's outer edge for the arris sits in a false minimum where the band has
    shrunk to nothing, which Gauss-Newton would not leave."""
    shifts = np.arange(-half, half + 0.25, 0.5)
    n_ok = prof.core.shape[0]
    if n_ok >= START_SUBSET_MIN_LINES and not prof.has_strip:
        # The shifts' costs differ by whole bands of misfit: every START_SUBSET_EVERY-th scan line ranks
        # them, and the few best are then costed on every line (at a third of the work: the start search
        # was two thirds of the far face's time). Not a proof of the same winner, but it was on every
        # parity case, 130 random renders and the noisy cases of test_edges_lines.
        every = max(START_SUBSET_EVERY, n_ok // START_SUBSET_LINES)
        sub, _ = prof.start_costs(sigma, mu0, shifts, every)
        shifts = shifts[np.sort(np.argsort(sub, kind="stable")[:START_SUBSET_KEEP])]
    costs, lams = prof.start_costs(sigma, mu0, shifts, 1)
    best = (math.inf, 0.0, 0.5)
    for shift, cost, lam_s in zip(shifts.tolist(), costs.tolist(), lams.tolist(), strict=True):
        if cost < best[0]:
            best = (cost, shift, lam_s)
    return prof.e0 + best[1], best[2]


_Fit = tuple[np.ndarray, float, float, float, float]  # the arrises, band level, blur, strip level and cost


def _other_strip_reading(
    prof: _Profiles, prior: _StripPrior, fit: _Fit, fit_blur: bool, n_iter: int, reach: float
) -> tuple[_Fit, float, _Fit | None]:
    """The better of a strip's two readings, how far the other puts the border (px, its weight included),
    and the other where it fits alike (:data:`READINGS_ALIKE`, :data:`READINGS_APART_PX` away), else None.

    A strip as bright as the far face (or as the hinge face) is also read as a door thinner (or thicker) by
    the strip's width, its far face wider (or its strip invisible): the two explain the profiles alike, and
    only their misfits tell them apart. Each is fitted from the other's place (arrises within ``reach`` px
    of the prediction); the better is kept, and the other weighs in as a second place for the border (its
    misfit excess at the scale of the residuals of one scan line: a model's error is common to all of them).
    But the better misfit is not always the door's (a 2.95 mm rounding as dark as the background, on a door
    rendered 2.5 mm thicker than its recipe, was read at its inner border, 2.98 mm thin, and passed:
    bench_surfaces.py --sets thin-arris --seed 2711 --wrong-thickness 2.5, door 23), so one that fits alike
    also stays for the thickness check (:attr:`FarFaceFit.other_reading_px`).
    """
    w_med = median(prof.strip)
    chosen = fit
    strip_doubt = 0.0
    others = []
    for sgn in (1.0, -1.0):
        alt = prof.gauss_newton(
            prior, chosen[0] + sgn * w_med, chosen[1], chosen[2], prior.mu0, fit_blur, n_iter
        )
        if np.all(np.abs(alt[0] - prof.e0) <= reach):
            others.append(alt)
    alike = None
    if others:
        ranked = sorted([chosen, *others], key=lambda t: t[4])
        chosen = ranked[0]
        per_line = chosen[4] / max(prof.core.shape[0], 1)
        for alt in ranked[1:]:
            q = math.exp(-min((alt[4] - chosen[4]) / (2.0 * max(per_line, 1e-300)), 50.0))
            shift = median(alt[0] - chosen[0])
            strip_doubt = max(strip_doubt, abs(shift) * math.sqrt(q / (1.0 + q)))
            if alike is None and alt[4] <= READINGS_ALIKE * chosen[4] and abs(shift) >= READINGS_APART_PX:
                alike = alt
    return chosen, strip_doubt, alike


def _band_readings(
    prof: _Profiles, prior: _StripPrior, fit: _Fit, fit_blur: bool, n_iter: int, reach: float
) -> tuple[_Fit, _Fit | None]:
    """A strip fit's band read both ways: the better reading, and the other where it fits alike (its misfit
    within :data:`READINGS_ALIKE` of the better's, its arrises within ``reach`` px of the prediction and
    :data:`READINGS_APART_PX` away), else None. A fit from the other reading's place whose band keeps
    its level's side has found the strip's other reading instead (:func:`_other_strip_reading`'s).

    A band at the background's or the hinge face's level (:func:`_other_band_reading`) leaves one step, the
    arris or the far face's back edge; the start search (common shifts within the window's half) and the
    strip's two readings do not reach the other. A door 2.5 mm thinner than its recipe, its far face as bright
    as its hinge face, was fitted with its back edge for the arris, beside a band at the background's level:
    measured 0.26 mm thin, it passed (bench_surfaces.py --sets thin-arris --seed 2611 --wrong-thickness -2.5,
    door 0); its other reading, 10.5 px in, misfits 4.4 times less. But the better misfit is not always the
    door's (at -1.5 mm, door 34: the back edge's reading misfits 0.82 times the true one's), so a reading that
    fits alike stays for the thickness check (:attr:`FarFaceFit.other_reading_px`)."""
    band_other = _other_band_reading(prof, fit[0], fit[1])
    if band_other == 0.0:
        return fit, None
    alt = prof.gauss_newton(
        prior, fit[0] + band_other, 0.0 if fit[1] >= 0.5 else 1.0, fit[2], prior.mu0, fit_blur, n_iter
    )
    if not np.all(np.abs(alt[0] - prof.e0) <= reach):
        return fit, None
    # a band that kept its side is the strip's other reading, not the band's
    if (alt[1] >= 0.5) == (fit[1] >= 0.5):
        return fit, None
    best, other = (alt, fit) if alt[4] < fit[4] else (fit, alt)
    if other[4] > READINGS_ALIKE * best[4] or abs(median(other[0] - best[0])) < READINGS_APART_PX:
        return best, None
    return best, other


def _other_band_reading(prof: _Profiles, e: np.ndarray, lam: float) -> float:
    """Where the band's other reading puts the arris, px from ``e`` (0 where the band's level tells the two
    readings apart): :attr:`FarFaceFit.other_reading_px` of a fit without a strip; with one, the start of
    the reading :func:`_band_readings` fits."""
    if min(abs(lam), abs(1.0 - lam)) > BAND_SIDE_LEVEL:
        return 0.0
    w_med = median(prof.band_width(e))
    if w_med < BAND_SIDE_MIN_PX:
        return 0.0
    # The band read as the background's: the step is the arris here, and the far face's back edge in
    # the other reading, whose arris lies inwards by its band's width, w / (1 + band_slope) (the band
    # widens as the arris moves in). Read as the hinge face's: the other way, by this band's width.
    return float(-w_med / max(1.0 + prof.band_slope, 0.1) if lam >= 0.5 else w_med)


@dataclass(frozen=True)
class _ArrisDoubts:
    """How well the fit places each arris: its standard error from the profile's noise ``e_sigma`` (px),
    and how far it moves per unit of error in the band level, the blur and the strip level (``de_dlam``,
    ``de_dsig``, ``de_dmu``: the last empty without a strip) with the strip level's doubt ``mu_doubt``."""

    e_sigma: np.ndarray
    de_dlam: np.ndarray
    de_dsig: np.ndarray
    de_dmu: np.ndarray
    mu_doubt: float

    def model_sigma(self, strip_doubt: float) -> float:
        """:attr:`FarFaceFit.model_sigma_px`: the level's and the blur's doubts (and a strip's, and the other
        place ``strip_doubt`` for its border that fits about as well) as the arris's move, px."""
        sigma = math.hypot(median(self.de_dlam) * LEVEL_DOUBT, median(self.de_dsig) * BLUR_DOUBT)
        if self.de_dmu.size:
            sigma = math.hypot(sigma, median(self.de_dmu) * self.mu_doubt, strip_doubt)
        return sigma


def _arris_doubts(prof: _Profiles, prior: _StripPrior, fit: _Fit, strip_shaded: bool) -> _ArrisDoubts:
    """The arrises' doubts at the answer ``fit`` (``strip_shaded``: the strip is a rounding)."""
    e, lam, sigma, mu, _ = fit
    h_ee, h_eg, b_e, H, b_g, rr = prof.sums(e, lam, sigma, mu)
    res_var = rr / max(prof.core.shape[1] - 1, 1)
    info = h_ee  # the arris derivative's squares
    e_sigma = np.sqrt(res_var / info)
    # How each arris would move to keep fitting its profile if the level or the blur were off. The
    # blur is not fitted here (the reference arris's): where the band is about as narrow as the blur,
    # a blur that is off pulls the fitted level with it, and the level moves the arris too, at most by
    # the band's (and a strip's) width: the readings a level can give lie between the arris and the
    # band's back edge.
    de_dlam = -h_eg[:, 0] / info
    lam_per_blur, mu_per_blur = _levels_per_blur(H, b_g, h_ee, h_eg, b_e, lam, mu, prior)
    pulled = de_dlam * lam_per_blur
    if prof.has_strip:
        pulled = pulled - h_eg[:, 2] / info * mu_per_blur
    reach = (prof.band_width(e) + prof.strip) / BLUR_DOUBT
    de_dsig = -h_eg[:, 1] / info + np.clip(pulled, -reach, reach)
    if not prof.has_strip:
        return _ArrisDoubts(e_sigma, de_dlam, de_dsig, np.zeros(0), 0.0)
    de_dmu = -h_eg[:, 2] / info
    # the strip level's own doubt (shared by every scan line: the Schur complement's, at the
    # residuals' scale; the blur not among the unknowns) and that of one level standing for a
    # strip's shading (a rounding's runs across it), as the band's
    h_eg[:, 1] = b_g[1] = 0.0
    H[1, :] = H[:, 1] = 0.0
    far_face_schur(H, b_g, h_ee, h_eg, b_e, lam, mu, LEVEL_PRIOR_WEIGHT, prior.pull_mu, prior.mu0)
    try:
        var_mu = float(np.linalg.inv(H)[2, 2]) * median(res_var)
    except np.linalg.LinAlgError:
        var_mu = prior.mu_sd**2
    # (a rounding's shading runs from the hinge face's level towards the far face's across the
    # strip: one level stands for it within about a uniform spread over that range)
    spread = abs(lam) / math.sqrt(12.0) if strip_shaded else 0.0
    mu_doubt = math.hypot(math.sqrt(max(min(var_mu, prior.mu_sd**2), 0.0)), max(LEVEL_DOUBT, spread))
    return _ArrisDoubts(e_sigma, de_dlam, de_dsig, de_dmu, mu_doubt)


def _levels_per_blur(
    H: np.ndarray,
    b_g: np.ndarray,
    h_ee: np.ndarray,
    h_eg: np.ndarray,
    b_e: np.ndarray,
    lam: float,
    mu: float,
    prior: _StripPrior,
) -> tuple[float, float]:
    """How far the far-face fit's band level (and a strip's level) move per px of error in the blur it was
    given, the arrises refitted along: from the step's sums at the answer
    (:func:`doorloc.vision.far_face_kernels.far_face_sums` with the blur's column, not changed here) through
    the Schur complement the fit solves, pulls included. Each at most ``1 / BLUR_DOUBT`` (a blur off by its
    doubt moves a level by at most its whole range, hinge face to background; the linear reading does not
    hold beyond it).

    Why: beside a band about as narrow as the blur the level and the blur trade off, and the fit's level
    follows whatever blur it was given. Counted as the blur's doubt at a fixed level, the arris's doubt
    missed that: a 1 px band beside a 1.4 px blur, its level read 0.55 for a far face about as bright as the
    hinge face, put the thickness 0.26 mm off at 7 sigma (bench_surfaces --seed 9100, hard_007; a blur off
    by 0.15 px moves that level by 0.55); with the level's pull counted, 2.5 sigma.
    """
    Hs, bs = H.copy(), b_g.copy()
    far_face_schur(Hs, bs, h_ee, h_eg, b_e, lam, mu, LEVEL_PRIOR_WEIGHT, prior.pull_mu, prior.mu0)
    # the levels' rows of the reduced normal equations, solved for a unit blur change (one or two
    # unknowns: in closed form; a strip's level is the third)
    if H.shape[0] == 3:
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


@dataclass(frozen=True)
class _FitSettings:
    """How :func:`_fit_arrises` fits: ``fit_blur`` and ``n_iter`` as :func:`subpixel_edges_far_face`'s, the
    window's half-size ``half`` and a strip's room either way ``n_strip`` (px), and ``strip_shaded`` (the
    strip is a rounding)."""

    fit_blur: bool
    n_iter: int
    half: int
    n_strip: int
    strip_shaded: bool


def _fit_arrises(
    prof: _Profiles, prior: _StripPrior, fit: _Fit, settings: _FitSettings
) -> tuple[_Fit, np.ndarray, float, float, str]:
    """The far-face fit on the usable lines from ``fit``'s blur and strip level (index units, px): the
    answer, each arris's standard deviation, the model's doubt (px), :attr:`FarFaceFit.other_reading_px`
    and, where that reading was fitted (beside a strip), what it reads the other way
    (:attr:`FarFaceFit.other_fitted`)."""
    strip_doubt = other_reading = 0.0
    other_kind = ""
    e, lam = _start(prof, fit[2], prior.mu0, settings.half)
    fit = prof.gauss_newton(prior, e, lam, fit[2], fit[3], settings.fit_blur, settings.n_iter)
    if prof.has_strip:
        reach = settings.half + settings.n_strip
        fit, band_other = _band_readings(prof, prior, fit, settings.fit_blur, settings.n_iter, reach)
        fit, strip_doubt, strip_other = _other_strip_reading(
            prof, prior, fit, settings.fit_blur, settings.n_iter, reach
        )
        for kind, other in (("band", band_other), ("strip", strip_other)):
            moved = median(other[0] - fit[0]) if other is not None else 0.0
            if abs(moved) >= READINGS_APART_PX:
                other_reading, other_kind = moved, kind
                break
    else:
        other_reading = _other_band_reading(prof, fit[0], fit[1])
    doubts = _arris_doubts(prof, prior, fit, settings.strip_shaded)
    return fit, doubts.e_sigma, doubts.model_sigma(strip_doubt), other_reading, other_kind


@dataclass(frozen=True)
class _Reach:
    """How :func:`subpixel_edges_far_face` reads its window (as :func:`subpixel_edges`): the search's half
    width and the plateaus' length, px; the start blur, px; the levels' smoothing along the edge, scan
    lines; and the look-up table to linear light (None: the values as they are)."""

    half: int
    plateau: int
    blur_px: float
    level_smooth: int
    lut: np.ndarray | None


@dataclass(frozen=True)
class _FarFaceWindow:
    """The profiles across the far arris, the hinge face at the low indices.

    ``scan`` the scan lines; ``w0`` the predicted band and ``ws`` the strip width per line, px;
    ``n_strip`` the room for a strip on either side, px; ``start`` the window's first pixel along the edge
    (its last when ``outward`` < 0);
    ``vals`` (N, length) the profiles in linear light; ``A``, ``B`` the hinge face's and the background's
    levels, ``D = B - A``; ``ok`` the usable lines; ``e0`` the predicted arris, index units."""

    reach: _Reach
    scan: np.ndarray
    outward: int
    w0: np.ndarray
    ws: np.ndarray
    has_strip: bool
    n_strip: int
    start: np.ndarray
    vals: np.ndarray
    A: np.ndarray
    B: np.ndarray
    D: np.ndarray
    ok: np.ndarray
    e0: np.ndarray


def _far_face_window(
    P: np.ndarray,
    scan: np.ndarray,
    centre: np.ndarray,
    band_px: np.ndarray,
    strip_px: np.ndarray | None,
    outward: int,
    reach: _Reach,
) -> _FarFaceWindow:
    """Gather the profiles across the far arris from the oriented plane ``P`` (arguments as
    :func:`subpixel_edges_far_face`), mirrored so that the hinge face is at the low indices."""
    half, plateau, blur_px = reach.half, reach.plateau, reach.blur_px
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
        vals, inside = gather_profiles(P, scan, start, length, lut=reach.lut)
    else:  # mirror so that the hinge face is at the low indices
        start = c0 + half + plateau + n_strip
        vals, inside = gather_profiles(P, scan, start - length + 1, length, lut=reach.lut)
        vals, inside = vals[:, ::-1], inside[:, ::-1]
    vals = vals.astype(np.float64)
    A = vals[:, :plateau].mean(axis=1)
    B = vals[:, -plateau:].mean(axis=1)
    ok = finite & inside.all(axis=1)
    if reach.level_smooth > 0 and scan.size:
        A = smooth_along(np.where(ok, A, np.nan), reach.level_smooth)
        B = smooth_along(np.where(ok, B, np.nan), reach.level_smooth)
    D = B - A
    ok &= np.isfinite(D) & (np.abs(D) > 0)
    e0 = plateau + n_strip + half + (centre - c0) * outward  # predicted arris, index units
    return _FarFaceWindow(reach, scan, outward, w0, ws, has_strip, n_strip, start, vals, A, B, D, ok, e0)


@dataclass(frozen=True)
class _Outcome:
    """The fit's arris per scan line, index units, and its standard error, px (NaN on unusable lines);
    the model's doubt and the other reading, px, and what that reads otherwise where it was fitted
    (:class:`FarFaceFit`)."""

    e_all: np.ndarray
    e_sigma: np.ndarray
    model_sigma: float
    other_reading: float
    other_kind: str = ""


def _fit_window(
    win: _FarFaceWindow, band_slope: float, strip_radiance: tuple[float, float], settings: _FitSettings
) -> tuple[_Fit, _Outcome]:
    """Fit the arrises, the band's level, the blur and the strip's level to the window's usable lines
    (:func:`_fit_arrises`); the start values where none is usable."""
    plateau, ok, has_strip, vals = win.reach.plateau, win.ok, win.has_strip, win.vals
    length = vals.shape[1]
    n_ok = int(ok.sum())
    # Only the core (between the plateaus) carries the edges; the plateaus fix A and B.
    prof = _Profiles(
        vals[ok, plateau : length - plateau],
        win.A[ok],
        win.D[ok],
        np.arange(plateau, length - plateau + 1, dtype=np.float64) - 0.5,
        win.e0[ok],
        win.w0[ok],
        band_slope,
        win.ws[ok] if has_strip else np.zeros(n_ok),  # (the kernels take a width on every line)
        has_strip,
    )
    prior = _StripPrior()
    if has_strip and n_ok:
        prior = _strip_prior(
            prof, np.concatenate([vals[ok, :plateau], vals[ok, -plateau:]], axis=1), strip_radiance
        )
    fit: _Fit = (prof.e0.copy(), 0.5, float(np.clip(win.reach.blur_px, 0.05, 5.0)), prior.mu0, math.nan)
    other_reading, other_kind = 0.0, ""
    e_all, e_sigma = np.full(len(win.scan), np.nan), np.full(len(win.scan), np.nan)
    model_sigma = float("nan")
    if n_ok:
        fit, e_sigma_ok, model_sigma, other_reading, other_kind = _fit_arrises(prof, prior, fit, settings)
        e_all[ok], e_sigma[ok] = fit[0], e_sigma_ok
    return fit, _Outcome(e_all, e_sigma, model_sigma, other_reading, other_kind)


def _far_face_answer(
    win: _FarFaceWindow, fit: _Fit, outcome: _Outcome, axis: Axis, band_slope: float, scale_to_8bit: float
) -> tuple[EdgeSamples, FarFaceFit]:
    """The edge points (``along`` the arris, px; levels in 8-bit grey levels) and the fit's summary."""
    scan, outward, start, e0 = win.scan, win.outward, win.start, win.e0
    e_all, e_sigma = outcome.e_all, outcome.e_sigma
    half, plateau, vals, A, B, D = win.reach.half, win.reach.plateau, win.vals, win.A, win.B, win.D
    _, lam, sigma, mu, _ = fit
    along = np.where(outward > 0, start + e_all, start - e_all)
    valid = win.ok & np.isfinite(along) & (np.abs(e_all - e0) <= half + win.n_strip) & np.isfinite(e_sigma)
    w_fit = np.maximum(win.w0 + band_slope * (e_all - e0), 0.0)
    band_med = median(w_fit[valid]) if np.any(valid) else float("nan")
    noise = np.sqrt(0.5 * (vals[:, :plateau].var(axis=1) + vals[:, -plateau:].var(axis=1)))
    # the brightest level seen (the saturation check): the band's fitted level only as far as a pixel of
    # the profile reaches it (a level fitted beyond them, 1258 grey levels on a chamfer read with the
    # wrong camera exponent, is no pixel's, and refused a door peaking at 228 as overexposed)
    band_level = np.minimum(A + lam * D, vals.max(axis=1))
    samples = EdgeSamples(
        axis,
        scan,
        np.where(valid, along, np.nan),
        D * outward * scale_to_8bit,
        noise * scale_to_8bit,
        np.full(len(scan), np.nan),
        np.maximum(np.maximum(A, B), band_level) * scale_to_8bit,
        valid,
    )
    fit_out = FarFaceFit(
        lam,
        sigma,
        band_med,
        median(e_sigma[valid]) if np.any(valid) else float("nan"),
        outcome.model_sigma,
        float(mu) if win.has_strip else float("nan"),
        outcome.other_reading,
        band_slope,
        outcome.other_kind,
    )
    return samples, fit_out


def subpixel_edges_far_face(
    window: ScanWindow,
    band: FarBand,
    blur_px: float = 1.0,
    fit_blur: bool = False,
    n_iter: int = 10,
) -> tuple[EdgeSamples, FarFaceFit]:
    """The far arris beside a visible far face, by fitting the whole profile across it.

    Seen from a camera beyond the far face's plane, the profile across the far arris is
    ``hinge face A | far face L, width w | background B``: two steps, the arris at ``e`` and the far
    face's back edge at ``e + w``. The band width follows from the geometry,
    ``w = band.width_px + band.slope (e - centre)`` (the back edge lies the door's width farther away and moves
    less), so each scan line has one unknown, ``e``; the band's relative level
    ``(L - A) / (B - A)`` (the same all along the edge under any smooth shading) and the optical blur
    are shared by all scan lines. They are fitted by Gauss-Newton on the pixel values, with each pixel
    modelled as a Gaussian-blurred step integrated over the pixel.

    Unlike the area estimator this uses the shape of the profile, so a narrow band brighter than the
    hinge face (which moves the profile's centroid the wrong way as the arris moves) does not make the
    estimate ill-conditioned.

    Parameters
    ----------
    window : ScanWindow
        The scan lines across the far arris, its predicted position on each, the window and plateaus as
        :func:`subpixel_edges` reads them; ``door_side`` the side of the hinge face, so that increasing
        ``along`` times ``-door_side`` leads from the hinge face across the arris.
    band : FarBand
        The far face's band beside the arris, and the strip of a chamfered or rounded arris.
    blur_px : float
        The optical blur (Gaussian sigma), px, e.g. from :func:`doorloc.vision.step_blur.step_blur` on
        another edge; with a band narrower than the blur, the band's level, its width and the blur trade off
        against each other, so the blur is best measured where the step is plain.
    fit_blur : bool
        Fit the blur too (starting at ``blur_px``); only sound where the band is much wider than the blur.
    n_iter : int
        Gauss-Newton iterations at the most.

    Returns
    -------
    samples : EdgeSamples
        ``along`` = the arris; ``step`` = ``B - A`` signed along ``along``.
    fit : FarFaceFit
    """
    w = window
    reach = _Reach(w.half, w.plateau, blur_px, w.level_smooth, w.lut)
    win = _far_face_window(
        oriented(w.plane, w.axis), w.scan, w.centre, band.width_px, band.strip_px, -w.door_side, reach
    )
    fit, outcome = _fit_window(
        win,
        band.slope,
        band.strip_radiance,
        _FitSettings(fit_blur, n_iter, w.half, win.n_strip, band.strip_shaded),
    )
    return _far_face_answer(win, fit, outcome, w.axis, band.slope, w.scale_to_8bit)
