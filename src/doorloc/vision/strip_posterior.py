"""The posterior of an arris strip's deficit along the valley where its outer border's place, its level and
the blur trade off (:func:`valley_posterior`), and the blur the door's other strips lend it as a prior.

:func:`doorloc.vision.arris_model.fit_strip_profile` profiles the strip's misfit over the border's offset
(the blur refitted at each offset: :class:`OffsetProfile`) under a shading model (:class:`StripShading`);
here that profile, resolved finely around each of its valleys, becomes the posterior of the deficit (the
fraction of the strip's width by which its area falls short of the hinge face's), times the deficit's
prior and, where the door's other strips read the blur, the blur's (:func:`strip_blur_priors`).

Why the blur's prior: one lens blurs every edge of the door alike, but a strip narrower than about twice the
blur shows one broad step that a wider blur with another strip level fits about as well. Fitted alone, such
a strip's posterior spreads over both readings (arris range bench, small set seed 12111, a 0.55 mm chamfer
under 1.43 px of blur: the bottom end's two valleys misfit alike, at blurs of 1.52 and 2.06 px, deficits
0.30 and 1.15, where the reference arris read 1.43 px alone; z in doubt by 0.16 mm, 0.017 mm off). The
other strips' reading of the blur (each from its own posterior, :attr:`ValleyPosterior.blur_reading`)
rules the second out: z in doubt by 0.09 mm, answered.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from doorloc.vision.arris_strip import StripEvaluation, StripProblem, posterior_moments

__all__ = [
    "OffsetProfile",
    "StripShading",
    "ValleyPosterior",
    "blur_log_prior",
    "strip_blur_priors",
    "near_a_plateau",
    "valley_posterior",
]

#: how far the blur may differ between the door's edges (one lens, but other distances from it, other
#: directions across the field, strips of other widths under a blur that is no exact Gaussian): the larger
#: of a tenth of a pixel and a tenth of the blur, 1 sigma
BLUR_BETWEEN_EDGES_PX = 0.1
BLUR_BETWEEN_EDGES_FRACTION = 0.1
#: the least standard deviation a strip's blur reading weighs with among the others' (one narrow valley
#: does not outweigh another strip's reading as sure as the model allows), px
BLUR_READING_FLOOR_PX = 0.02
#: a strip whose level lies within this fraction of the contrast of the face's or the background's shows
#: one step (:func:`_one_step_readings`): a few per cent is what a halo's skirt or a shading's drift gives it
ONE_STEP_LEVEL = 0.1
#: how far the misfit the noise alone leaves may lie above what the plateaus' noise predicts, as a fraction
#: of it: that noise is the median over the lines of their two plateaus' mean spread, while in linear light
#: the dark side's noise and the bright side's differ and the transition's lies between. A miss within it
#: is no evidence of a model that misses (a 0.97 mm chamfer under 1.7 px of blur misfit by 0.23 of the
#: noise's share; its pair's difference, as large, told its one step apart rightly: tests/vision/
#: test_locate.py, the thinner door's twin at its recipe's thickness)
NOISE_SHARE_DOUBT = 0.25


@dataclass(frozen=True)
class OffsetProfile:
    """The coarse profile of the misfit over the outer border's offset (px from its prediction, along the
    mirrored scan towards the door), the blur refitted at each offset.

    ``grid`` the offsets (px), ``blur`` the blur fitted at each (px), ``evaluation`` the free shading's
    fit there, ``step`` the grid's spacing (px); ``lo_lim``, ``hi_lim`` the offsets that keep the
    background and the face in view (px) and ``limited`` whether the grid was cut to them.
    """

    grid: np.ndarray
    blur: np.ndarray
    evaluation: StripEvaluation
    step: float
    lo_lim: float
    hi_lim: float
    limited: bool


@dataclass(frozen=True)
class StripShading:
    """The strip's shading model in use and its best fit: ``basis`` (cells, levels), the border's offset
    and the blur (px), their evaluation; ``alt`` the other shading model's misfit, deficit, and its linear
    parameters beyond the one in use; ``lit`` the lit arc's deficit and its own doubt, a prior on the free
    shading's (when the arc is not in use); ``model_doubt`` what the model itself may miss in the deficit
    (fractions of the strip's width; a told light's Lambertian arc)."""

    basis: np.ndarray
    offset: float
    blur: float
    evaluation: StripEvaluation
    alt: tuple[float, float, int] | None = None
    lit: tuple[float, float] | None = None
    model_doubt: float = 0.0


@dataclass(frozen=True)
class ValleyPosterior:
    """The deficit's posterior along the valley (:func:`valley_posterior`): its mean and standard
    deviation (fractions of the strip's width), the valleys' refined fits ``modes`` (offset px, blur px,
    evaluation), the least misfit over the profiles ``chi_min`` and the misfit's scale between valleys
    ``t_glob`` (normalised variance); ``blur_reading`` the blur's mean and standard deviation along the
    valley before any prior on it (px): what this strip tells the door's other strips."""

    deficit: float
    sd: float
    modes: list[tuple[float, float, StripEvaluation]]
    chi_min: float
    t_glob: float
    blur_reading: tuple[float, float] = (math.nan, math.inf)


def valley_posterior(
    prob: StripProblem,
    coarse: OffsetProfile,
    shading: StripShading,
    basis0: np.ndarray,
    noise: float,
    prior: tuple[float, float],
    blur_prior: tuple[float, float] | None = None,
) -> ValleyPosterior:
    """The posterior of the deficit along the valley of the border's offset (px), under ``shading``, the
    prior ``prior`` (mean, sd) times the misfit's likelihood; the other shading model not yet weighed.

    ``blur_prior`` (mean, sd px; None: none) weighs each offset by the blur that fits it best there (the
    misfit profiled over the blur, not integrated over it): what it rules out is a valley whose blur lies
    far from the other strips'.
    """
    basis, d0, s0, ev0 = shading.basis, shading.offset, shading.blur, shading.evaluation
    grid, sg, ev = coarse.grid, coarse.blur, coarse.evaluation
    # The posterior of the deficit along the valley: the coarse profile over the whole search range, and
    # around each of its valleys a fine one (its width from that valley's curvature) that resolves it.
    # Another valley (a strip at the face's level, seen as one at the background's a strip's width away)
    # may be as deep as the optimum's but narrower than the coarse step: its best point is refined too.
    dof_b = max(prob.y.size - basis.shape[1] - 4, 1)
    # The residual variance per binned row: the noise, and what the model misses. Within one valley that
    # is the scale of the misfit (T_loc). Between valleys, and along a flat one, the misfit's excess is the
    # model's error, the same on every bin (the same shape at about the same phase): it does not average
    # down over the bins as the noise does, so there the bins weigh as one (T_glob). A model that misses
    # its profiles by more than their noise then cannot choose between two places for the border by
    # less than its own error.
    t_b = float(ev0.chi2[0]) / dof_b
    T_loc = max(t_b, noise**2)
    T_glob = noise**2 + prob.count.size * max(t_b - noise**2, 0.0)
    c = ev.chi2
    local = [
        i
        for i in range(c.size)
        if abs(grid[i] - d0) > 1.0 and (i == 0 or c[i] <= c[i - 1]) and (i == c.size - 1 or c[i] <= c[i + 1])
    ]
    modes = [(d0, s0, ev0)] + [
        prob.refine(float(grid[i]), float(sg[i]), basis, n_iter=8)
        for i in sorted(local, key=lambda i: c[i])[:2]
    ]
    modes += _other_readings(prob, modes, coarse, basis, float(ev0.chi2[0]), T_glob)
    keep, fines = _fine_profiles(prob, modes, coarse, basis, T_loc)
    if basis is basis0:  # the coarse profile is this model's already
        sgc, evc = sg, ev
    else:
        sgc, evc = prob.profile_blur(grid, sg, basis, n_iter=2)
    chi_min = min(float(evc.chi2[keep].min()) if keep.any() else np.inf, *(float(f[1].min()) for f in fines))
    # the best fit's miss beyond the noise: what the other reading of a strip's one step may gain by its
    # free level taking up a skirt that the blur model misses (_one_step_readings)
    miss = max(chi_min - (1.0 + NOISE_SHARE_DOUBT) * dof_b * noise**2, 0.0)
    one_step = _one_step_readings(prob, fines)
    # log-likelihood: the coarse points against the best at T_glob; each valley's fine points against
    # the valley's own best at T_loc, and that best against the overall best (:func:`_valley_penalty`)
    ll = [-(evc.chi2[keep] - chi_min) / (2.0 * T_glob)] + [
        -(f[1] - f[1].min()) / (2.0 * T_loc)
        - _valley_penalty(float(f[1].min()) - chi_min, T_glob, miss if other else 0.0, noise)
        for f, other in zip(fines, one_step, strict=True)
    ]
    deltas = np.concatenate([grid[keep], *(f[0] for f in fines)])
    order = np.argsort(deltas)
    deltas = deltas[order]
    dfc = np.concatenate([evc.deficit[keep], *(f[2] for f in fines)])[order]
    logp = np.concatenate(ll)[order] - 0.5 * ((dfc - prior[0]) / prior[1]) ** 2
    blurs = np.concatenate([sgc[keep], *(f[3] for f in fines)])[order]
    # the blur this strip reads on its own (the mean and sd of its posterior, before the other strips' say)
    blur_reading = posterior_moments(deltas, blurs, logp)
    if blur_prior is not None:
        logp = logp + blur_log_prior(blurs, blur_prior)
    deficit, post_sd = posterior_moments(deltas, dfc, logp)
    deficit, post_sd = _with_other_shading(shading, deltas, dfc, logp, deficit, post_sd, T_glob)
    return ValleyPosterior(deficit, post_sd, modes, chi_min, T_glob, blur_reading)


def _valley_penalty(excess: float, T_glob: float, miss: float, noise: float) -> float:
    """The negative log-likelihood of a valley whose best misfit exceeds the least by ``excess``: at the
    scale ``T_glob`` (normalised variance), but for the other reading of a strip's one step the part of it
    within the best fit's own ``miss`` beyond the noise (and its doubt, ``NOISE_SHARE_DOUBT``) weighs at
    that miss's scale, at most half a unit (:func:`_one_step_readings`; ``miss`` 0 elsewhere)."""
    if miss <= 0.0:
        return excess / (2.0 * T_glob)
    t_miss = max(T_glob, noise**2 + miss)
    return max(excess - miss, 0.0) / (2.0 * T_glob) + min(excess, miss) / (2.0 * t_miss)


def _one_step_readings(prob: StripProblem, fines: Sequence[tuple[np.ndarray, ...]]) -> list[bool]:
    """Which of the finely profiled valleys (offsets px, misfits, deficits, blurs: :func:`_fine_profiles`)
    is the other reading of the best one's single step (their best points' deficits within
    ``ONE_STEP_LEVEL`` of 0 and of 1, one each, their offsets a strip's width apart): as much of its excess
    misfit as the best fit's own miss beyond the noise then counts at most half a log unit.

    Two valleys that put the strip's one step at the same place (one at the face's level, the other at
    the background's a strip's width outwards) differ only in the side of the step where the model's
    free strip level lies, and so in which of the step's skirts that level takes up: what tells them
    apart is the skirts' shape, where the blur model is weakest. A model that misses by more than their
    difference cannot choose between them. Weighed as other valleys are, a lens halo (30 % of the light
    at 3.1 times the 0.87 px core) made a chamfer at the face's level, read as one at the background's
    whose level took up the halo's skirt, fit e^10 better: z 1.35 mm off at 15 sigma (arris range bench,
    halo set, seed 210104; its gain was 0.66 of the best fit's miss). Beyond that miss the excess is the
    model's, not the skirts': a grained door's bottom end whose other reading misfit by 5.5 times the
    best's miss stays answered (surfaces bench, combined set, seed 64105, door 6)."""
    # each valley's best point: its offset (px) and deficit
    points = [(float(f[0][i]), float(f[2][i])) for f in fines for i in [int(np.argmin(f[1]))]]
    best_offset, best_deficit = points[int(np.argmin([float(f[1].min()) for f in fines]))]
    w_med = float(np.median(prob.width))
    return [
        near_a_plateau(deficit, ONE_STEP_LEVEL)
        and near_a_plateau(best_deficit, ONE_STEP_LEVEL)
        and abs(deficit - best_deficit) > 0.5
        and abs(abs(offset - best_offset) - w_med) < 1.0  # a strip's width apart, within a pixel
        for offset, deficit in points
    ]


def near_a_plateau(deficit: float, within: float) -> bool:
    """Whether a strip fitted at ``deficit`` lies within ``within`` of the hinge face's level (deficit 0) or
    the background's (1): it shows one plain step, which a strip at the other level a strip's width away
    draws as well. False for a NaN deficit."""
    return min(abs(deficit), abs(deficit - 1.0)) <= within


def _other_readings(
    prob: StripProblem,
    modes: list[tuple[float, float, StripEvaluation]],
    coarse: OffsetProfile,
    basis: np.ndarray,
    chi2_first: float,
    T_glob: float,
) -> list[tuple[float, float, StripEvaluation]]:
    """The other reading of each valley of ``modes`` (offset px, blur px, evaluation) a strip's width
    either way, refined (offset and blur px, as :meth:`StripProblem.refine`), where no valley refined lies
    within half the coarse step of it and its misfit lies within 20 log units (``T_glob`` the misfit's scale
    between valleys) of the first valley's ``chi2_first``.

    A strip that shows one step may be a strip at the face's level whose border is that step, or one at the
    background's a strip's width outwards; under a sharp lens the second valley is narrower than the coarse
    step, which may step over it (a 2.4 mm rounding as dark as the background, 0.36 px of blur: its bottom
    end read at the face's level alone, z 2.14 mm off at 32 sigma under a light stated wrong). Sought beside
    every valley, not only the shading's first: the one step may be another valley's (2.9 and 1.9 mm
    roundings as dark as the background, 0.31-0.54 px of blur, the door's own light: the best valley's other
    reading, a twentieth of its misfit, unsought, and the doors 2.55 and 1.73 mm off in z at 30 sigma)."""
    # why many parameters: the strip problem, its valleys and coarse profile, the shading basis and the two misfit figures the valley posterior has already formed
    grid, step = coarse.grid, coarse.step
    w = float(np.median(prob.width))
    found: list[tuple[float, float, StripEvaluation]] = []
    for dm, sm, _ in modes:
        for d in (dm - w, dm + w):
            if grid[0] <= d <= grid[-1] and min(abs(m[0] - d) for m in [*modes, *found]) > 0.5 * step:
                other = prob.refine(d, sm, basis, n_iter=8)
                if (float(other[2].chi2[0]) - chi2_first) / (2.0 * T_glob) < 20.0:
                    found.append(other)
    return found


def _fine_profiles(
    prob: StripProblem,
    modes: list[tuple[float, float, StripEvaluation]],
    coarse: OffsetProfile,
    basis: np.ndarray,
    T_loc: float,
) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]]:
    """Each valley of ``modes`` (offset px, blur px, evaluation) profiled finely over the border's offset,
    12 of its standard deviations wide (from its curvature at the misfit's scale ``T_loc``, at most the
    coarse step): per valley the offsets, misfits, deficits and blurs (the blur refitted at each, px); and
    which of the coarse profile's offsets lie outside them (``keep``)."""
    grid, step = coarse.grid, coarse.step
    keep = np.ones(grid.size, bool)
    fines: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    for k, (dm, sm, em) in enumerate(modes):
        if k and min(abs(dm - d1) for d1, _, _ in modes[:k]) < 0.2:
            continue  # refined into a valley already resolved
        assert em.hess is not None
        try:
            s_m = math.sqrt(max(float(np.linalg.inv(em.hess[0] / 2.0)[0, 0]) * T_loc, 0.0))
        except np.linalg.LinAlgError:
            s_m = step
        s_m = float(np.clip(s_m, 1e-3, step))
        fine = dm + s_m * np.linspace(-6.0, 6.0, 25)
        sbf, evf = prob.profile_blur(fine, np.full(fine.size, sm), basis, n_iter=2)
        keep &= np.abs(grid - dm) > 6.0 * s_m
        fines.append((fine, evf.chi2, evf.deficit, sbf))
    return keep, fines


def _with_other_shading(
    shading: StripShading,
    deltas: np.ndarray,
    dfc: np.ndarray,
    logp: np.ndarray,
    deficit: float,
    post_sd: float,
    T_glob: float,
) -> tuple[float, float]:
    """The deficit's mean and standard deviation (fractions of the strip's width) with a rounding's other
    shading model weighed in: the lit arc's deficit as a prior, the other model as one more valley.
    ``deltas`` (px), ``dfc`` and ``logp``: the offsets, deficits and log-posterior of the valley."""
    lit, alt, ev0 = shading.lit, shading.alt, shading.evaluation
    if lit is not None:
        # The lit arc's shading, a prior on the free shading's deficit: the free levels trade off with the
        # border's place along a valley that the light's shading cuts short where the two agree. Its width
        # is never narrower than the two disagree by (a prior the data contradict must not narrow them).
        lit_sd = max(lit[1], abs(deficit - lit[0]))
        held, held_sd = posterior_moments(deltas, dfc, logp - 0.5 * ((dfc - lit[0]) / lit_sd) ** 2)
        # A prior that narrows one valley leaves the mean between the data's and its own; one that takes it
        # beyond both has chosen between the valleys of a skewed posterior, which it cannot tell apart any
        # better than the profiles (a 1.2 mm rounding in shadow at its silhouette: its first pass's bottom
        # end read 1.005 for a free 0.89 and an arc's 0.97, and the final pass went to a valley with
        # another blur, z in doubt by 0.18 mm): there the free shading's posterior stands.
        if min(deficit, lit[0]) <= held <= max(deficit, lit[0]) and held_sd <= post_sd:
            deficit, post_sd = held, held_sd
    if alt is not None:
        # The other shading model (Lambert arc or free shading) is one more place for the answer, weighed
        # as another valley is: a rounding whose two models disagree is in doubt by their difference.
        # Each linear parameter more that a model has costs it a factor e (Akaike's weight): without it
        # the free shading's better misfit, which its extra parameters buy anywhere, outweighed an arc
        # as good as it by 1500 to 1 and took the answer to its own valley with the sigma of the arc's
        # (arris bench seed 1557, a 2.9 mm rounding's bottom end: z 0.15 mm off at 2.1 sigma, where the arc
        # had the border right; with the factor 0.09 mm at about 1 sigma).
        log_w = (alt[0] - float(ev0.chi2[0])) / (2.0 * T_glob) + alt[2]
        w_alt = math.exp(-min(max(log_w, -30.0), 30.0))
        mean = (deficit + w_alt * alt[1]) / (1.0 + w_alt)
        post_sd = math.sqrt(post_sd**2 + w_alt / (1.0 + w_alt) ** 2 * (alt[1] - deficit) ** 2)
        deficit = mean
    return deficit, post_sd


def blur_log_prior(blur: np.ndarray, blur_prior: tuple[float, float] | None) -> np.ndarray:
    """The log density (up to a constant) of the blurs ``blur`` (px) under ``blur_prior`` (mean, sd px); 0
    without a prior."""
    if blur_prior is None:
        return np.zeros_like(blur, dtype=float)
    return -0.5 * ((blur - blur_prior[0]) / blur_prior[1]) ** 2


def strip_blur_priors(readings: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """Each strip's prior on its blur (mean, sd px) from the blur the door's *other* strips read.

    ``readings``: per line, the blur its strip fit reads on its own (mean and sd of its posterior, px;
    :attr:`ValleyPosterior.blur_reading`). A line's prior is the other lines' readings weighed by their
    sds (at least ``BLUR_READING_FLOOR_PX``), its sd theirs with how far the blur may differ between
    edges (``BLUR_BETWEEN_EDGES_PX``, ``BLUR_BETWEEN_EDGES_FRACTION``) and half the others' spread: two
    strips that disagree (texture beside one led its fit to another valley) lend a wide prior, not their
    mean. A line no other strip reads has none (a door without an arris, the first pass).
    """
    sure = {k: m for k, m in readings.items() if math.isfinite(m[0]) and math.isfinite(m[1])}
    out: dict[str, tuple[float, float]] = {}
    for k in readings:
        others = [m for j, m in sure.items() if j != k]
        if not others:
            continue
        means = np.array([m for m, _ in others])
        w = 1.0 / np.maximum(np.array([s for _, s in others]), BLUR_READING_FLOOR_PX) ** 2
        mean = float(w @ means / w.sum())
        spread = 0.5 * float(means.max() - means.min())
        between = max(BLUR_BETWEEN_EDGES_PX, BLUR_BETWEEN_EDGES_FRACTION * mean)
        out[k] = (mean, math.sqrt(1.0 / float(w.sum()) + between * between + spread * spread))
    return out
