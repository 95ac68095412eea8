"""The virtual sharp corner behind a chamfered or rounded arris.

An arris of size ``a`` shows as a strip between the background and the hinge face. Its outer border is
the chamfer's far edge, or on a rounding the silhouette where the view ray grazes the cylinder; its inner
border the tangent line on the hinge face. Both are straight lines whose places follow from the
geometry (:class:`doorloc.arris.ArrisSection`); the strip's brightness does not: it depends on the light,
the wood and the camera's response. Where an edge estimator that assumes a plain step puts the edge inside
the strip depends on that brightness, so locate measures it:

1. :func:`arris_geometry` (:mod:`doorloc.vision.arris_geometry`): from the current pose, each arris's
   cross-section seen from the camera: the outer border's place on the outline plane (``y = a``; inwards
   from the sharp corner's line, mm), the inner border's, and the map from the fraction of the strip's image width to the surface angle ``theta``;
2. :func:`fit_strip_profile`: the strip's shading, fitted to the profiles of many scan lines at once
   (linear light, each normalised by its own two plateaus): background | strip | hinge face, blurred by a
   Gaussian and integrated over the pixels, with the outer border's offset and the blur free, and the strip
   a chamfer's constant level or a rounding's shading (free and piecewise linear, or a Lambert arc where
   that fits about as well; the two weighed where they disagree; where the arc fits worse, its deficit
   under the light fitted to it is a prior on the free shading's, as wide as the two disagree). What it
   returns is the strip's *deficit*: the fraction of its width by which the area of the strip falls short
   of the hinge face, the mean of its posterior along the valley where the border's offset and the
   strip's level trade off (:mod:`doorloc.vision.strip_posterior`; the blur the door's other strips read
   is a prior on its blur where they read one);
3. :func:`doorloc.vision.arris_lines.arris_edges`: per scan line the area estimator (blur-free: it only uses areas) with that deficit,
   ``e = K - S / D - w * deficit``, which puts every edge point on the outer border, then refined by
   fitting the strip's fitted shape to the line with its two levels free (its compiled border fit: the
   area estimate takes in the face's texture beside the strip, the shape fit hardly); the caller moves
   it to the sharp corner's line by the geometry.

What the deficit leaves in doubt (the posterior's standard deviation, widened by the blur model's doubt)
is reported per line as ``arris_correction_sigma_mm`` for the uncertainty budget.

Cost: profiles binned by the outer border's sub-pixel phase (``_PHASE_BINS`` rows), the levels solved
linearly in every evaluation (variable projection) with closed form derivatives in the offset and the
blur, grids of offsets evaluated as one batch: a few ms per edge (~60-90 ms with numerical Jacobians).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from doorloc.vision.arris_geometry import ArrisGeometry, arris_geometry
from doorloc.vision.arris_strip import (
    StripEvaluation,
    StripProblem,
    lit_basis,
    pixel_terms,
    strip_basis,
)
from doorloc.vision.arris_strip_kernels import mix_cells
from doorloc.vision.stated_light import StatedLight, stated_light_explains
from doorloc.vision.strip_posterior import (
    OffsetProfile,
    StripShading,
    blur_log_prior,
    valley_posterior,
)
from doorloc.vision.strip_prior import PRIOR_DEFICIT, PRIOR_SIGMA

__all__ = ["ArrisGeometry", "StripFit", "arris_geometry", "fit_strip_profile"]

#: sub-intervals of a rounding's strip (uniform in image width) over which its shading is taken constant in
#: the fit, at most
_STRIP_CELLS = 16
#: narrowest part of a rounding's strip whose shading level the fit leaves free, px
_PART_PX = 1.5
#: sub-pixel phases of the outer border over which the fit bins its profiles
_PHASE_BINS = 8
#: Lambert shadings (of the 41 lights tried) refined at their best place against a rounding's free shading
_SHADINGS_REFINED = 4
#: scan lines the shading fit uses at most (spread evenly over the edge)
FIT_LINES = 40
#: plausible error of the Gaussian blur model, px (sets the model's doubt in the strip's deficit)
BLUR_DOUBT = 0.1
#: least doubt in the deficit of a rounding's Lambert shading under the light fitted to it (a real finish is
#: no exact Lambertian, nor its light one direction): 0.03 of the strip's width
LIT_DEFICIT_FLOOR = 0.03


@dataclass(frozen=True)
class StripFit:
    """The strip's shading fitted over many scan lines (:func:`fit_strip_profile`).

    Attributes
    ----------
    deficit : float
        ``1/w`` times the integral over the strip of ``(face - strip) / (face - background)``: 0 for a strip as
        bright as the hinge face (the edge is the outer border), 1 for one as dark as the background.
    deficit_sigma : float
        Its standard deviation: the posterior's along the valley where the border's offset and the strip's
        level trade off (:func:`fit_strip_profile`), widened by the blur model's doubt, and where the same
        strip read from another pick of its scan lines lands in another valley, by their difference
        (:func:`doorloc.vision.arris_lines.arris_edges`).
    offset_px : float
        Outer border's offset from where the pose put it, px (along the mirrored scan, towards the door).
    blur_px : float
        Gaussian blur sigma that fits best, px.
    misfit : float
        Residual RMS of the fit over the plateaus' noise (about 1 when the model explains the profiles).
    levels : ndarray
        The strip's relative level ``(strip - background) / (face - background)`` on ``_STRIP_CELLS`` cells.
    model : ndarray (N, P)
        The fitted profiles (noise-free), for the profiles that went into the fit.
    border : ndarray (N,)
        Their fitted outer border (coordinates of ``x``), px.
    model_deficit : float
        The deficit of the fitted profiles ``model`` (the best fit's, where ``deficit`` is the posterior
        mean along the valley).
    deficit_at_blur : callable or None
        ``blur_px -> deficit``: the deficit of the best fit with the blur held at another value (the
        border's offset searched again over the fit's range), for the caller's check of the blur against
        the image's other strips (one lens, one blur).
    clipped_share : float
        The share of the strip's scan lines with white-clipped pixels (two or more at the image's top code)
        beside the border: a highlight the sensor cut off, whose shading the fit cannot read (the gate refuses
        above ``LocateConfig.max_clipped_arris_fraction``).
    stated_light_misfit : float or None
        A rounding's misfit under the cell's stated light over its free shading's (None: no light stated, or
        no rounding); beyond ``stated_light.STATED_LIGHT_MISFIT_RATIO`` the stated light was not used on this strip.
    misfit_under_lights : callable or None
        ``directions (n, 3) -> ratios (n,)``: a rounding's misfit under lights from ``directions`` (unit
        vectors towards the light, cell frame) over its free shading's, found as ``stated_light_misfit`` is
        for the stated light (a light sought from the doors: :mod:`doorloc.vision.light_search`); None on
        a chamfer, or where the strip's surface normals are not known.
    grey_misfit : float
        The fitted profiles' residual RMS in the camera's grey levels over the plateaus' grey-level noise,
        which readings with different exponents compare on (:func:`doorloc.vision.arris_lines.arris_edges`).
    blur_reading : (float, float)
        The blur this strip reads on its own, the mean and standard deviation of its posterior along the
        valley (px; before any prior on the blur), which the door's other strips take as theirs
        (:func:`doorloc.vision.strip_posterior.strip_blur_priors`).
    """

    deficit: float
    deficit_sigma: float
    offset_px: float
    blur_px: float
    misfit: float
    levels: np.ndarray
    model: np.ndarray
    border: np.ndarray
    model_deficit: float
    deficit_at_blur: Callable[[float], float] | None = field(default=None, compare=False, repr=False)
    clipped_share: float = 0.0
    stated_light_misfit: float | None = None
    misfit_under_lights: Callable[[np.ndarray], np.ndarray] | None = field(
        default=None, compare=False, repr=False
    )
    grey_misfit: float = math.nan
    blur_reading: tuple[float, float] = (math.nan, math.inf)

    @property
    def stated_light_used(self) -> bool | None:
        """Whether the cell's stated light shaded this rounding (None: no light stated, or no rounding)."""
        return None if self.stated_light_misfit is None else stated_light_explains(self.stated_light_misfit)


def _lit_deficit(
    prob: StripProblem,
    tried: list[tuple[int, float, float, StripEvaluation]],
    best: tuple[float, float, StripEvaluation],
    free_basis: np.ndarray,
    t_free: float,
) -> tuple[float, float]:
    """The deficit of a rounding's Lambert shading (the light's direction fitted) and its doubt.

    The doubt: the spread of the deficits of the lights tried, each weighed by its misfit (the lights the
    profiles cannot tell apart), how far the free shading's deficit lies from the arc's at the arc's own
    place and blur (where the profiles ask for another shading than the light's), and ``LIT_DEFICIT_FLOOR``
    (a real surface is no exact Lambertian, nor its light one direction).
    """
    d1, s1, ev1 = best
    chi = np.array([float(ev.chi2[0]) for *_, ev in tried] + [float(ev1.chi2[0])])
    dfs = np.array([float(ev.deficit[0]) for *_, ev in tried] + [float(ev1.deficit[0])])
    wts = np.exp(-(chi - chi.min()) / (2.0 * t_free))
    wts /= wts.sum()
    spread = math.sqrt(max(float(wts @ (dfs - float(ev1.deficit[0])) ** 2), 0.0))
    free_here = float(prob.evaluate(np.array([d1]), np.array([s1]), free_basis).deficit[0])
    doubt = math.sqrt(LIT_DEFICIT_FLOOR**2 + spread**2 + (free_here - float(ev1.deficit[0])) ** 2)
    return float(ev1.deficit[0]), doubt


def fit_strip_profile(
    r: np.ndarray,
    x: np.ndarray,
    outer: np.ndarray,
    width: np.ndarray,
    geom: ArrisGeometry,
    noise: float,
    blur0: float = 1.0,
    search_px: float = 0.0,
    prior: tuple[float, float] = (PRIOR_DEFICIT, PRIOR_SIGMA),
    shared: float = 0.0,
    light: StatedLight | None = None,
    blur_prior: tuple[float, float] | None = None,
) -> StripFit | None:
    """Fit the strip's shading to normalised profiles (module docstring, step 2).

    Parameters
    ----------
    r : ndarray (N, P)
        Profiles across the edge in linear light, each normalised to 0 on the background and 1 on the hinge
        face (by its own plateaus), ordered from the background towards the door.
    x : ndarray (P,)
        Pixel-centre coordinates of the columns of ``r``, px.
    outer, width : ndarray (N,)
        Predicted outer border (same coordinates as ``x``) and strip width, px, per profile.
    geom : ArrisGeometry
        The strip's geometry (for a rounding's shading basis).
    noise : float
        Typical noise of ``r`` (normalised), for the misfit.
    blur0 : float
        Starting blur, px.
    search_px : float
        How far the outer border may lie from its prediction beyond 2 px (a first pose that took the
        strip's inner border for the edge), px.
    prior : (float, float)
        The deficit's prior, mean and standard deviation (:func:`deficit_prior`; default the neutral one).
    shared : float
        Variance (normalised) that the profiles binned at one phase share and their number does not average
        down: the rounding to grey levels where the noise is too weak to dither it. Measured: a 1.2 mm
        rounding under 0.06 grey levels of noise (arris bench seed 11524's door lit from +40 deg instead of
        -40) had its border placed 0.18 mm off at 14 sigma, the misfit's valleys weighed as if the
        rounding averaged out over the bins' ~5 profiles; with it, at 6.5 sigma (the free shading's two
        places fit alike there and no Lambert arc fits as well: not fixed).
    light : StatedLight or None
        The cell's light (its direction in the cell frame and how well it is known): a rounding is shaded
        under it (:func:`_told_light_shading`).
    blur_prior : (float, float) or None
        The blur the door's other strips read (mean, sd px: :func:`doorloc.vision.strip_posterior.
        strip_blur_priors`), a prior on this strip's blur along its valley; None: the blur free.

    Returns
    -------
    StripFit or None
        None when there are too few profiles.

    Notes
    -----
    The profiles pin the strip's *area* (where an equivalent plain step would lie) to a small fraction of
    a pixel, but not how that area splits between the border's place and the strip's level: on a strip
    narrower than the blur the two trade off along a valley (a dark strip whose border lies outwards looks
    like a bright one whose border lies inwards; a strip at the background's or the face's level is a
    plain step at either border). A local optimum and its curvature would then report one end of the
    valley with a confidence the data do not give. So the deficit is the mean of its posterior along the
    valley: the misfit profiled over the border's offset (the blur refitted at each; every valley of a
    coarse profile over the search range refined and resolved finely), times the prior ``prior`` (the
    strip's radiance a fraction of the face's: :func:`deficit_prior`), and its standard deviation the posterior's,
    widened by how far the deficit moves when the blur model is off by ``BLUR_DOUBT``. Within a valley
    the misfit weighs at the scale of the residuals; between valleys (and along a flat one) the
    residuals' excess over the noise counts as model error common to all the profiles, so that a model
    that misses its profiles by more than their noise does not choose between two places for the border
    by less than that.
    """
    # why many parameters: the profiles, their predicted strip and noise, and six independent settings with defaults (start blur, search reach, the deficit's prior, the undithered variance, the cell's light, the blur's prior) that the callers pass by keyword
    # why long: its docstring (ten parameters, and the notes on the valley the posterior is taken along); the body is 20 lines
    ok = np.all(np.isfinite(r), axis=1) & np.isfinite(outer) & np.isfinite(width) & (width > 0)
    r, outer, width = r[ok], outer[ok], width[ok]
    if r.shape[0] < 5:
        return None
    round_ = geom.section.profile == "round"
    w_med = float(np.median(width))
    # a rounding's shading changes across its strip: cells of at most half a pixel; a chamfer's is one level
    n_cells = int(np.clip(math.ceil(2.0 * w_med), 4, _STRIP_CELLS)) if round_ else 1
    prob = StripProblem(r, x, outer, width, n_cells, _PHASE_BINS, noise, shared)
    basis0 = _free_basis(n_cells, w_med, round_)
    coarse, best = _coarse_offsets(prob, x, outer, width, basis0, blur0, search_px + max(2.0, w_med + 1.0))
    shading = free = StripShading(basis0, *best)
    light_misfit: float | None = None
    if round_:
        told = None
        if light is not None and geom.normals_cell is not None:
            told, light_misfit = _told_light_shading(prob, geom, n_cells, coarse, shading, light)
        shading = told if told is not None else _rounding_shading(prob, geom, n_cells, noise, coarse, shading)
    fit = _posterior_fit(prob, (r, outer, width), coarse, shading, basis0, noise, prior, blur_prior)
    if not round_ or geom.normals_cell is None:
        return fit
    return replace(
        fit,
        stated_light_misfit=light_misfit,
        misfit_under_lights=lambda directions: np.array(
            [m for _, _, m in _under_lights(prob, geom, n_cells, coarse, free, directions)]
        ),
    )


def _free_basis(n_cells: int, w_med: float, round_: bool) -> np.ndarray:
    """The strip's shading basis with its levels free, ``(n_cells, levels)``: on a rounding piecewise linear
    across the strip's width (``w_med`` its median width, px), on a chamfer one level."""
    if round_:
        # A rounding's shading free, piecewise linear across its strip on parts at least _PART_PX wide
        # (what the blur leaves of the shading's detail): a Lambert model of the arc would need the light,
        # and a light whose terminator crosses the arc, a glossy finish or another reflectance would lead
        # it astray (0.36-0.58 mm on the arris bench), where free levels follow any shading.
        n_parts = int(np.clip(math.floor(w_med / _PART_PX), 1, 8))
        # piecewise linear in the strip's width (hat functions on n_parts + 1 knots, at the cells' centres)
        tau = (np.arange(n_cells) + 0.5) / n_cells
        return np.maximum(0.0, 1.0 - np.abs(tau[:, None] * n_parts - np.arange(n_parts + 1)[None, :]))
    return np.ones((n_cells, 1))  # a chamfer's strip: one level


def _coarse_offsets(
    prob: StripProblem,
    x: np.ndarray,
    outer: np.ndarray,
    width: np.ndarray,
    basis0: np.ndarray,
    blur0: float,
    reach: float,
) -> tuple[OffsetProfile, tuple[float, float, StripEvaluation]]:
    """The misfit's coarse profile over the border's offset within ``reach`` px either way (``x``, ``outer``,
    ``width`` as :func:`fit_strip_profile`'s, px), and its best point refined: offset (px), blur (px) and
    evaluation."""
    # The offset has local minima on narrow strips (strip and border trade places): profile the misfit over
    # a grid of offsets across the search range (the blur refitted at each), and refine from the best.
    # A strip at the face's level and one at the background's are both a plain step, at the outer or at
    # the inner border: the search (and the posterior) spans both, a strip's width and more either way.
    step = max(0.2, reach / 10.0)
    grid = np.arange(-reach, reach + 1e-9, step)
    # A place for the border that puts the background (or the face) beyond the profile is not measured by
    # it: the level there is free, and a strip of any level fits what remains (the levels' prior alone
    # sets it). Such a place beat the right one by misfit on the final pass, whose window has no room for
    # a strip's width outwards, and every line's edge left its window (arris bench seeds 7075, 7558: a
    # strip about as bright as the face, a 2.7 mm chamfer's bottom end and a 2.5 mm rounding's far arris
    # lost). The background and the face keep a pixel and twice the blur in view.
    margin = 1.0 + 2.0 * max(blur0, 0.7)
    lo_lim, hi_lim = float(np.max(x[0] + margin - outer)), float(np.min(x[-1] - margin - (outer + width)))
    inside = (grid >= lo_lim) & (grid <= hi_lim)
    limited = bool(inside.sum() >= 3)
    if limited:
        grid = grid[inside]
    sg, ev = prob.profile_blur(grid, np.full(grid.size, max(blur0, 0.7)), basis0, n_iter=2)
    i0 = int(np.argmin(ev.chi2))
    best = prob.refine(float(grid[i0]), float(sg[i0]), basis0)
    return OffsetProfile(grid, sg, ev, step, lo_lim, hi_lim, limited), best


def _border_places(coarse: OffsetProfile, centre: float, reach: float) -> np.ndarray:
    """Places for the outer border (px, as :func:`_coarse_offsets`' offsets) a quarter pixel apart within
    ``reach`` px of ``centre``, those that keep the background and the face in view where the coarse profile
    was cut to them: where a fixed shading model is refined at its own best place."""
    places = centre + np.arange(-reach, reach + 1e-9, 0.25)
    return places[(places >= coarse.lo_lim) & (places <= coarse.hi_lim)] if coarse.limited else places


def _rounding_shading(
    prob: StripProblem,
    geom: ArrisGeometry,
    n_cells: int,
    noise: float,
    coarse: OffsetProfile,
    free: StripShading,
) -> StripShading:
    """A rounding's shading: the free one (``free``) or a Lambert arc where that explains the profiles
    about as well, the other model's misfit and deficit kept (``alt``) and, where the free shading stays,
    the arc's deficit as a prior on it (``lit``). Offsets and blurs in px, as :func:`_coarse_offsets`'."""
    basis0, d0, s0, ev0 = free.basis, free.offset, free.blur, free.evaluation
    # The free shading lets the level next to the silhouette trade off with the border's place; a
    # Lambert arc (the light's direction unknown, its terminator anywhere) does not. It is taken where
    # it explains the profiles about as well as the free shading (the extra parameters' worth of misfit
    # and three standard deviations of it more, at the misfit's scale).
    t_free = max(float(ev0.chi2[0]) / max(prob.y.size - basis0.shape[1] - 4, 1), noise**2)
    cands = [strip_basis(geom, n_cells, None, False)] + [
        strip_basis(geom, n_cells, t, lb)
        for t in np.linspace(0.025, 0.975, 20) * float(geom.theta.max())
        for lb in (False, True)
    ]
    # Each shading at many places for the border, not only at the free shading's best: where the
    # strip's outer part is in shadow (at the background's level) the free shading has two places for
    # the border that fit alike, and the arc's own best place is the one that tells them apart (arris
    # bench seed 11524, a 1.2 mm rounding lit from 58 deg above: at the free shading's place the arc
    # missed by 75 noise units, at its own 0.9 px away by 3).
    # The places: steps of a quarter pixel within 2.5 px of the free shading's (the coarse profile's
    # steps grow with the strip's width, 1.3 px on a 12 px strip, wider than an arc's valley).
    places = _border_places(coarse, d0, 2.5)
    if places.size == 0:
        places = np.array([d0])
    # (the free shading's own place scored with them, last, for the start it had alone before)
    at = np.append(places, d0)
    costs = prob.chi2_many(prob.pixel_terms(at, np.full(at.size, s0)), cands)  # (shadings, places)
    costs[1:] = np.where(costs[1:] < costs[:1] * 0.98, costs[1:], np.inf)  # a terminator must pay
    here, costs = costs[:, -1], costs[:, :-1]
    # the shadings best at some place, each refined there (its own blur: the free shading's is not
    # the arc's where the two place the border apart)
    best_at = np.argmin(costs, axis=1)
    starts = [
        (int(j), float(places[best_at[j]]), s0)
        for j in np.argsort(costs[np.arange(len(cands)), best_at])[:_SHADINGS_REFINED]
        if np.isfinite(costs[j, best_at[j]])
    ]
    starts.append((int(np.argmin(here)), d0, s0))  # the best shading at the free shading's place
    tried = [(j, *prob.refine(d, sd, cands[j], n_iter=4)) for j, d, sd in starts]
    j, d1, s1, _ = min(tried, key=lambda t: float(t[3].chi2[0]))
    b1 = cands[j]
    d1, s1, ev1 = prob.refine(d1, s1, b1)
    extra = max(basis0.shape[1] - b1.shape[1], 1)
    if (float(ev1.chi2[0]) - float(ev0.chi2[0])) / t_free <= extra + 3.0 * math.sqrt(2.0 * extra):
        return StripShading(b1, d1, s1, ev1, alt=(float(ev0.chi2[0]), float(ev0.deficit[0]), extra))
    alt = (float(ev1.chi2[0]), float(ev1.deficit[0]), -extra)
    lit = _lit_deficit(prob, tried, (d1, s1, ev1), basis0, t_free)
    return StripShading(basis0, d0, s0, ev0, alt=alt, lit=lit)


def _told_light_shading(
    prob: StripProblem,
    geom: ArrisGeometry,
    n_cells: int,
    coarse: OffsetProfile,
    free: StripShading,
    light: StatedLight,
) -> tuple[StripShading | None, float]:
    """A rounding's shading under the cell's light (:func:`doorloc.vision.arris_strip.lit_basis`): refined at
    its own best place for the border (steps of a quarter pixel within 2 px of the free shading's, as the
    Lambert arcs are), and its misfit over the free shading's (``free``). None for the shading where that
    ratio exceeds ``stated_light.STATED_LIGHT_MISFIT_RATIO``: a light stated wrong (a sign of the azimuth, a lamp moved)
    fits far worse than a free shading, and placed a 2.9 mm rounding's door 0.37 mm off at 4.5 sigma (arris
    bench round set, seed 8122, the light stated 110 deg off); such a strip is fitted as without a light.
    Its doubt: ``LIT_DEFICIT_FLOOR`` (the model's own) and what the deficit moves when the light is turned
    by its stated sigma (:meth:`StatedLight.turned`, each turn refitted from the best place), in
    quadrature. Offsets and blurs in px, as :func:`_coarse_offsets`'.

    Why: the free shading's levels trade off with the border's place along a valley the profiles hardly
    cut (a rounding of 1-2 mm under 1-2 px of blur is placed to a few hundredths of a mm), and the light
    cannot be fitted from the strips either (they fit any direction about alike); a light measured once
    for the cell leaves the strip two unknowns, its albedo and the background's share. Measured on the
    arris bench's round set (seed 7900, the renderer's light told): answered 11 -> 14 of 16, x / z RMS
    0.0155 / 0.0067 -> 0.0032 / 0.0024 mm. The turns: a light stated 40 deg off, yet within the ratio, put
    a 0.74 mm rounding's door (small set, seed 11100) 0.109 mm off in x at 3.2 sigma; at 1.8 with them."""
    [(basis, (d1, s1, ev1), misfit)] = _under_lights(prob, geom, n_cells, coarse, free, light.direction_cell)
    # (the free shading is not weighed in as another model, as a Lambert arc fitted to the strip is: with
    # its more levels it fits the noise better, and weighed by its misfit it took the answer back to its own
    # valley: a 0.74 mm rounding, small set seed 10903, x 0.004 -> 0.085 mm)
    if not stated_light_explains(misfit):
        return None, misfit
    moved = [
        float(prob.refine(d1, s1, lit_basis(geom, n_cells, t), n_iter=6)[2].deficit[0])
        - float(ev1.deficit[0])
        for t in light.turned()
    ]
    light_doubt = math.sqrt(sum(m * m for m in moved) / len(moved)) if moved else 0.0
    return StripShading(basis, d1, s1, ev1, model_doubt=math.hypot(LIT_DEFICIT_FLOOR, light_doubt)), misfit


def _under_lights(
    prob: StripProblem,
    geom: ArrisGeometry,
    n_cells: int,
    coarse: OffsetProfile,
    free: StripShading,
    directions: np.ndarray,
) -> list[tuple[np.ndarray, tuple[float, float, StripEvaluation], float]]:
    """A rounding's Lambert shading under lights from ``directions`` (``(n, 3)`` unit vectors, cell frame):
    per light its basis, its fit refined at its own best place for the border (of steps of a quarter pixel
    within 2 px of the free shading's ``free``: :meth:`StripProblem.refine_best_placed`; offset and blur
    px) and its misfit over the free shading's."""
    bases = [lit_basis(geom, n_cells, d) for d in np.atleast_2d(directions)]
    places = np.array([free.offset, *_border_places(coarse, free.offset, 2.0).tolist()])
    fits = prob.refine_best_placed(places, free.blur, bases, n_iter=6)
    chi_free = max(float(free.evaluation.chi2[0]), 1e-300)
    return [(b, f, float(f[2].chi2[0]) / chi_free) for b, f in zip(bases, fits, strict=True)]


def _posterior_fit(
    prob: StripProblem,
    lines: tuple[np.ndarray, np.ndarray, np.ndarray],
    coarse: OffsetProfile,
    shading: StripShading,
    basis0: np.ndarray,
    noise: float,
    prior: tuple[float, float],
    blur_prior: tuple[float, float] | None = None,
) -> StripFit:
    """The :class:`StripFit`: the posterior's deficit (:func:`valley_posterior`), widened by the blur
    model's doubt, and the fitted profiles of the valley the posterior favours on every line of ``lines``
    (the profiles ``r``, their predicted outer border and strip width, px, as :func:`fit_strip_profile`'s;
    ``prob`` holds them binned)."""
    post = valley_posterior(prob, coarse, shading, basis0, noise, prior, blur_prior)
    deficit, post_sd, chi_min, T_glob = post.deficit, post.sd, post.chi_min, post.t_glob
    basis, grid = shading.basis, coarse.grid
    r, outer, width = lines
    n_cells = prob.n_cells

    # The fitted shape (the caller's area-estimate correction and line-by-line fit start from it) is the
    # valley's that the posterior favours, not the lowest misfit's: two places for the border can misfit
    # alike (a strip at the face's level, and one at the background's a strip's width outwards whose
    # background then lies beyond the window, so that any level fits it), and there the prior decides,
    # as it does for the deficit. Taking the lowest misfit there put every line's edge a strip's width
    # out of its window (arris bench seed 7075, a 2.7 mm chamfer as bright as the face: bottom end lost).
    # The blur's prior, where the other strips lend one, weighs the valleys too.
    def _log_post(sm: float, em: StripEvaluation) -> float:
        dev = (float(em.deficit[0]) - prior[0]) / prior[1]
        blur_term = float(blur_log_prior(np.array([sm]), blur_prior)[0])
        return -(float(em.chi2[0]) - chi_min) / (2.0 * T_glob) - 0.5 * dev * dev + blur_term

    d0, s0, ev0 = max(post.modes, key=lambda m: _log_post(m[1], m[2]))

    # The model's own doubt: a strip narrower than the blur looks like a wider blur with another strip
    # level, and the real optics are no exact Gaussian. How far the deficit moves when the blur is off by
    # BLUR_DOUBT (the offset refitted):
    sgm = np.maximum(s0 + np.array([-BLUR_DOUBT, BLUR_DOUBT]), 0.05)
    e1 = prob.offset_at_blur(np.full(2, d0), sgm, basis, n_iter=3)
    moved = float(np.max(np.abs(e1.deficit - ev0.deficit[0])))
    sigma = min(math.hypot(post_sd, moved, shading.model_doubt), prior[1])

    # the fitted profiles themselves (every line, not binned), for the caller's window correction
    bounds = (outer[None, :, None] + d0) + width[None, :, None] * prob.frac
    prim, _, _ = pixel_terms(prob.edges, bounds, np.array([s0]))
    M, const = mix_cells(basis, n_cells)
    model = (prim @ M + const)[0] @ ev0.coef[0]  # (N, P)
    resid = model - r
    dof = max(r.size - basis.shape[1] - 4, 1)
    misfit = math.sqrt(float(np.sum(resid**2)) / dof) / max(noise, 1e-6)
    c0, cb, band = ev0.coef[0, 0], ev0.coef[0, 1], ev0.coef[0, 2:]
    levels = (basis @ band - c0) / (cb - c0)

    def deficit_at_blur(blur_px: float) -> float:
        """The best fit's deficit with the blur held at ``blur_px``: the offset's coarse profile over the
        search range, then Newton steps on the offset alone."""
        b = max(float(blur_px), 0.1)
        d = grid[int(np.argmin(prob.evaluate(grid, np.full(grid.size, b), basis).chi2))]
        return float(prob.offset_at_blur(np.array([d]), np.array([b]), basis, n_iter=6).deficit[0])

    return StripFit(
        deficit,
        sigma,
        d0,
        s0,
        misfit,
        levels,
        model,
        outer + d0,
        float(np.mean(1.0 - levels)),
        deficit_at_blur,
        blur_reading=post.blur_reading,
    )
