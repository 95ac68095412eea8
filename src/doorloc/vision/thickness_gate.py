"""The thickness's checks in locate's gate: the door's measured thickness against its recipe
(:func:`thickness_check`), the readings that weigh in it (a far face's other reading, :func:`other_reading`;
a side arris's strip read the other way, :func:`strip_other_readings`; the far silhouette's contrast,
:func:`far_silhouette_contrast`), its figures for the answer (:func:`thickness_diagnostics`) and the doubt an
unverified thickness reports (:func:`reported_budget`). Thicknesses in mm, contrasts in grey levels (0-255
scale, linear light).

A thickness wrong at confidence is ``thickness_mismatch`` (a wrong door or recipe); one the image cannot
verify is ``uncertain``, refused or reported as unverified by ``locate.thickness_check``. A miss the image's
own ambiguities explain (a strip read the other way, a far silhouette without contrast) is such a thickness,
naming what the image could not see; refused under either policy where the reference arris is in doubt (the
door's x is then as far off).
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.cell import DoorSize
from doorloc.limits import DOOR_RANGES_MM
from doorloc.vision import quality as q
from doorloc.vision.config import LocateConfig
from doorloc.vision.far_band import FarFaceFit
from doorloc.vision.state import Refined
from doorloc.vision.strip_posterior import near_a_plateau
from doorloc.vision.uncertainty import Budget

__all__ = [
    "BAND_LEVEL_RANGE",
    "MISREAD_SIGMAS",
    "PLAIN_STEP_DEFICIT",
    "UNRESOLVED_BAND_BLURS",
    "far_silhouette_contrast",
    "other_reading",
    "reported_budget",
    "shows_one_step",
    "strip_other_readings",
    "thickness_check",
    "thickness_diagnostics",
]


#: a far face's band at most this many blurs (Gaussian sigma) wide, at the fit and at the recipe's thickness,
#: cannot be told from the arris by the profile's shape: only the step it leaves is seen
UNRESOLVED_BAND_BLURS = 1.0
#: the far face's relative level (0 the hinge face's, 1 the background's) a band may have: a far face lit from
#: its side can be brighter than the hinge face by half the contrast, or darker than the background
BAND_LEVEL_RANGE = (-0.5, 1.5)


def other_reading(r: Refined, door: DoorSize, t_tol: float) -> tuple[float, float | None]:
    """How far a far face's other reading lies, mm, and that reading of the thickness where it is weighed."""
    pose, far_fit, far_beside = r.pose, r.far_fit, r.far_beside
    if not far_beside or far_fit is None:
        return 0.0, None
    # A far face whose band looks like the background or like the hinge face reads two ways, a band's width
    # apart (edges.FarFaceFit.other_reading_px), and the image cannot tell which: the other reading is
    # weighed however far (_readings_split), wherever it puts a door thickness doorloc accepts
    # (limits.DOOR_RANGES_MM), and the reported sigma reaches it at 2 sigma. Readings beyond twice the
    # tolerance were once left out (the fitted one judged alone): wrong doors passed, thin doors whose far
    # face, as bright as the hinge face, ended where the recipe puts the far arris (bench_surfaces.py --sets
    # thin --n 40 --seed 2611 --wrong-thickness -2.5, doors 13 and 32: read 13.2 and 16.1 px inwards beside
    # a band at the background's level; and +2.5, door 3, 11.9 px outwards beside one at the hinge face's).
    other_mm = far_fit.other_reading_px * pose.scale_mm_per_px
    if other_mm != 0.0:
        lo, hi = DOOR_RANGES_MM["thickness_mm"]
        a_door = lo <= pose.thickness_mm + other_mm <= hi
        return other_mm, (pose.thickness_mm + other_mm if a_door else None)
    other_mm = _unresolved_band_reading(far_fit, door.thickness_mm - pose.thickness_mm, pose.scale_mm_per_px)
    return other_mm, (pose.thickness_mm + other_mm if 0.0 < abs(other_mm) <= 2.0 * t_tol else None)


def _unresolved_band_reading(far_fit: FarFaceFit, to_recipe_mm: float, scale_mm_per_px: float) -> float:
    """The recipe's thickness as the far face's other reading, mm from the fitted one (0 where it is not one).

    A band narrower than the blur shows only the step it leaves (the arris's place plus the band's width
    times how unlike the hinge face it is), and that step is explained as well by an arris farther in
    beside a wider band of about the hinge face's level, or farther out beside a narrower one: along that
    valley only the profile's shape tells the readings apart, which wood grain and JPEG blocks outweigh
    (bench_surfaces' thin set, seed 2514, door 22: a 32.5 mm door yawed -1.8 deg, its far face a 1.1 px band
    as bright as the grained hinge face under a 1.75 px blur, was fitted as a 0.07 px band and measured
    0.27 mm thick at 6 sigma; the fitted reading misfits 20 % less than the true one). Where the recipe's
    reading lies on that valley (its band unresolved too, at a level a far face can have; or wider than the
    blur at the hinge face's level or the background's, :func:`shows_one_step`), it is weighed."""
    if not (far_fit.blur_px > 0 and scale_mm_per_px > 0 and math.isfinite(far_fit.band_px)):
        return 0.0
    moved_px = to_recipe_mm / scale_mm_per_px  # the arris's move to the recipe's reading, outwards positive
    w_fit = far_fit.band_px
    w_recipe = w_fit + far_fit.band_slope * moved_px
    widest = UNRESOLVED_BAND_BLURS * far_fit.blur_px
    if not (0.0 < w_recipe and w_fit <= widest):
        return 0.0
    if w_recipe > widest:
        # A band wider than the blur shows its shape, unless it is as bright as the hinge face (or as dark as
        # the background): then it joins that side and only one plain step is seen, the far face's back edge
        # (or the arris). bench_surfaces.py --sets grain_strong --seed 5157, door 27 (a 31.1 mm door under
        # ambient light, its far face 7 % brighter than the hinge face and 2.0 px wide under a 1.5 px blur)
        # was fitted as a 0.16 px band darker than black at the step and measured 0.47 mm thick at a sigma
        # of 0.026 mm; rendered without grain, noise, JPEG or shading, 0.44 mm. The step is then the fitted
        # profile's area edge, its band's level unclipped: a sliver beyond either plateau's level moves it
        # (there by -0.35 px: the recipe's band is then 0.08 of the contrast brighter than the hinge face,
        # one step; with the level clipped, 0.27 brighter, two).
        area_step = w_fit * (1.0 - far_fit.band_level)
        return to_recipe_mm if shows_one_step(1.0 - (area_step - moved_px) / w_recipe) else 0.0
    # the step the fitted reading leaves, px beyond its arris (a collapsed band's level says nothing: within
    # the band), and the level the recipe's band needs to leave it
    step = w_fit * (1.0 - min(max(far_fit.band_level, 0.0), 1.0))
    level = 1.0 - (step - moved_px) / w_recipe
    lo, hi = BAND_LEVEL_RANGE
    return to_recipe_mm if lo <= level <= hi else 0.0


def far_silhouette_contrast(r: Refined) -> float | None:
    """The grey-level step (0-255 scale, linear light) between the background and the far arris's strip next to
    its outer border (a rounding's silhouette, a chamfer's outer edge); None where the far arris has no strip fit.

    The strip fit's level next to the outer border, as a fraction of the background-to-face step, times that
    step: where it is small the border's place cannot be seen and the thickness rests on the strip's inner end
    and the shading model alone."""
    if "far" not in r.arris_fits or r.far_beside:
        return None
    strip, _ = r.arris_fits["far"]
    s = r.samples["far"]
    step = s.step[np.isfinite(s.step)]
    if strip.levels.size == 0 or step.size == 0:
        return None
    return float(abs(strip.levels[0]) * np.median(np.abs(step)))


#: a side arris's strip fitted within this of the hinge face's level (deficit 0) or the background's (1)
#: shows one plain step, which its other reading puts at the strip's other border
PLAIN_STEP_DEFICIT = 0.2


def shows_one_step(deficit: float) -> bool:
    """Whether an arris strip fitted at ``deficit`` shows one plain step (within ``PLAIN_STEP_DEFICIT`` of the
    hinge face's level 0 or the background's 1), which its other reading puts at the strip's other border;
    not a strip with a level between, nor one beyond either plateau's (brighter than the face, darker than
    the background): two steps, no other reading. A NaN deficit lies near nothing: True, as the comparisons
    give it (callers that need a finite one test it)."""
    return math.isnan(deficit) or near_a_plateau(deficit, PLAIN_STEP_DEFICIT)


#: a thickness within the tolerance that misses the recipe by more than this many of its sigmas, where a side
#: arris's other reading lands within as many, is that arris's misreading as likely as a door off its recipe
MISREAD_SIGMAS = 3.0


def strip_other_readings(r: Refined) -> dict[str, float]:
    """Per side arris whose strip the fit read as one plain step: how far its other reading moves the
    thickness, mm (positive: thicker).

    A strip at the hinge face's level and one at the background's both show one step, the first at the
    strip's outer border and the second at its inner border, a strip's width apart, and the profiles fit
    both alike: only the strip's radiance prior (:data:`doorloc.vision.strip_prior.STRIP_RADIANCE`) chose
    between them. A deficit ``d`` places the outer border ``d`` strip widths outwards from where a plain step
    would, so the other reading (deficit 1 for a strip read at the face's level, 0 for one read at the
    background's) moves the edge by the deficits' difference times the width. The far arris beside a seen
    far face is left out (its band's own other reading is :func:`other_reading`'s)."""
    shifts: dict[str, float] = {}
    for k in ("reference", "far"):
        if k not in r.arris_fits or (k == "far" and r.far_beside):
            continue
        strip, band_px = r.arris_fits[k]
        d = strip.model_deficit
        if not math.isfinite(d) or not shows_one_step(d):
            continue  # a strip with a level between: two steps, no other reading
        other_deficit = 1.0 if d < 0.5 else 0.0
        shifts[k] = (other_deficit - strip.deficit) * band_px * r.pose.scale_mm_per_px
    return shifts


def thickness_check(
    r: Refined,
    door: DoorSize,
    cfg: LocateConfig,
    t_sigma: float,
    other: float | None,
    silhouette: float | None = None,
    strip_shifts: dict[str, float] | None = None,
    hint: str | None = None,
    far_unread: q.Refusal | None = None,
) -> tuple[list, list, bool]:
    """The thickness's checks against the recipe: the refusals that stand under either policy, those of a
    thickness the image cannot verify (refused under ``refuse``, reported under ``report``), and whether the
    thickness is uncertain. ``silhouette``: the far arris's outer border's contrast, grey levels
    (:func:`far_silhouette_contrast`); below the edges' ``min_contrast`` the reason names it, and a miss beyond
    the tolerance by no more than the recipe's arris size is one the image cannot verify, not a wrong door.
    ``strip_shifts``: the side arrises' other readings (:func:`strip_other_readings`), weighed where the
    fitted thickness misses the recipe. ``hint``: the clause naming the term that weighs most in the
    thickness's doubt and what lifts it, where moving the door does not (the unchecked camera response, an
    arris strip); None: check the door, or move it and take the image again. ``far_unread``: the far
    arris's strip fit took its edge's transition (:func:`doorloc.vision.quality.check_strips_took_their_edge`):
    where its border lies is not known, and the thickness is neither right nor wrong (that refusal, as one of
    a thickness the image cannot verify)."""
    # why many parameters: the refined state, the door, the settings, and the gate's six findings about the thickness (its sigma, the far face's other reading, the silhouette's contrast, the side strips' other readings, the clause naming its doubt, an unread far strip), each its own check's
    if far_unread is not None:
        return [], [far_unread], True
    pose, far_beside, t_tol = r.pose, r.far_beside, cfg.thickness_tolerance_mm
    split = _readings_split(r, door, t_tol, t_sigma, other)
    if split is not None:
        return [], [split], True
    # (the fitted reading where the two are as near)
    readings = [pose.thickness_mm] + ([other] if other is not None else [])
    nearest = min(readings, key=lambda t: abs(t - door.thickness_mm))
    mismatch = q.check_thickness(nearest, door.thickness_mm, t_tol, sigma=t_sigma)
    # a thickness that misses the recipe (beyond the tolerance, or within it by more than its doubt allows)
    # may be a side arris's strip read the other way
    missed = mismatch is not None or abs(nearest - door.thickness_mm) > MISREAD_SIGMAS * t_sigma
    misread = (
        _misread_strips(nearest, door, t_tol, t_sigma, strip_shifts or {}, mismatch is not None)
        if missed
        else None
    )
    if misread is not None:
        refusal, keys = misread
        # a misread reference arris moves the door's x as far as its thickness: refused under either policy
        return ([refusal], [], True) if "reference" in keys else ([], [refusal], True)
    unseen = _silhouette_unseen(silhouette, cfg)
    if mismatch is not None:
        if unseen is None or abs(nearest - door.thickness_mm) - t_tol > door.arris_mm:
            return [mismatch], [], True
        # The far arris's outer border has no contrast: the strip's shading alone placed it, anywhere across
        # the strip, so a miss that the arris's size can hold is not a wrong door (dark wood as dark as the
        # background, ambient light: `bench_arris_range.py --n 32 --seed 9100 --sets dark`, seeds 15109 and
        # 15130, valid 2.24 and 2.96 mm roundings measured 1.62 and 1.65 mm thin at 3.2 and 4.2 sigma,
        # silhouettes of 0.39 and 0.1 grey levels, were refused `thickness_mismatch`). The pose does not
        # rest on the far arris: refused under `refuse`, reported unverified under `report`.
        miss = (
            f"the door's thickness cannot be checked: it measures {nearest:.2f} mm against "
            f"{door.thickness_mm:.2f} mm (tolerance {t_tol:g} mm), a miss its {door.arris_mm:.3g} mm "
            f"{'rounding' if door.arris_profile == 'round' else 'chamfer'} may hide"
        )
        return [], [q.Refusal("uncertain", miss + unseen)], True
    if abs(nearest - door.thickness_mm) + 3.0 * t_sigma <= t_tol:
        return [], [], False
    measured = (
        f"the door's thickness cannot be checked: it measures {nearest:.2f} +- {3 * t_sigma:.2f} mm against "
        f"{door.thickness_mm:.2f} mm (tolerance {t_tol:g} mm)"
    )
    edge_on = " with its far face seen nearly edge-on" if far_beside else ""
    if unseen is not None:
        why = unseen
    elif hint is not None:
        why = f"{edge_on}, {hint}"
    else:
        why = f"{edge_on}; check the door and the recipe, or move the door a little along X and take the image again"
    return [], [q.Refusal("uncertain", measured + why)], True


def _readings_split(
    r: Refined, door: DoorSize, t_tol: float, t_sigma: float, other: float | None
) -> q.Refusal | None:
    """Where the profiles beside the far arris read two ways (the far face's band, at the background's or the
    hinge face's level; or the arris's strip, fitted alike: :attr:`FarFaceFit.other_fitted`; ``other`` the
    second reading's thickness, mm) and one passes the recipe's tolerance while the other does not, the
    ``uncertain`` refusal that names both; else None.

    The check cannot take the reading nearer the recipe there: that passes a wrong door whose far face's back
    edge lies where the recipe puts the far arris (a door 1.5 mm thinner than its recipe, measured 0.71 mm
    thick with the back edge's reading, which misfit 0.82 times the true one's: bench_surfaces.py --sets
    thin-arris --seed 2611 --wrong-thickness -1.5, door 34); nor call the door wrong where the reading that
    misses is the worse fit's (valid doors 34 and 38 of the same set, measured 1.18 and 2.09 mm thick
    beside the better fit's band at the background's level). The same holds for the strip's two readings:
    at seed 2711 (+2.5 mm) and 3011 (+1.5, +2.5 mm) three wrong doors whose rounding was read at its other
    border passed."""
    if other is None or r.far_fit is None or r.far_fit.other_reading_px == 0.0:  # (the recipe's, unresolved)
        return None
    fitted = r.pose.thickness_mm
    passes = [q.check_thickness(t, door.thickness_mm, t_tol, sigma=t_sigma) is None for t in (fitted, other)]
    if passes[0] == passes[1]:
        return None
    if r.far_fit.other_fitted != "strip":
        side = "background" if r.far_fit.band_level >= 0.5 else "hinge face"
        reading = (
            "the one step beside the far arris is the far face's back edge rather than the arris (or the "
            f"reverse): the far face looks like the {side}"
        )
        light = "light the far face differently from the hinge face and the background"
    else:
        reading = (
            "the far arris's strip is read at its other border, a strip's width away: its shading is hard to "
            "tell from the faces beside it"
        )
        light = "light the far arris so that it stands apart from the hinge face and the far face"
    return q.Refusal(
        "uncertain",
        f"the door's thickness cannot be checked: it measures {fitted:.2f} mm against {door.thickness_mm:.2f} "
        f"mm (tolerance {t_tol:g} mm), or {other:.2f} mm if {reading}, and the image fits both alike; {light}, "
        "or check that the right door is in the fixture",
    )


def reported_budget(
    budget: Budget, door: DoorSize, cfg: LocateConfig, silhouette: float | None, uncertain: bool
) -> Budget:
    """The answer's budget as reported: a thickness the check found ``uncertain`` with its far silhouette
    unseen (:func:`far_silhouette_contrast` ``silhouette`` under ``min_contrast``) carries the strip's width
    in its reported doubt, the ``far_silhouette`` term (not weighed by the check, which already found it
    unverified; a verified thickness keeps its figure)."""
    unseen = _unseen_silhouette_sigma_mm(door, silhouette, cfg)
    if not uncertain or not unseen > 0:
        return budget
    return budget.with_reported_thickness_term("far_silhouette", unseen)


def _unseen_silhouette_sigma_mm(door: DoorSize, silhouette: float | None, cfg: LocateConfig) -> float:
    """What an unseen far silhouette leaves in doubt of the thickness, 1 sigma, mm: where the far arris's outer
    edge has less contrast than edges need, the strip's shading alone places it, anywhere across the strip,
    the recipe's arris size wide (uniform: the size over sqrt(12)); 0 where the silhouette is seen, or there
    is no strip. (On `bench_arris_range.py --sets dark --seed 9100` a valid 2.96 mm rounding measured 1.65 mm
    thin where its thickness's own sigma was 0.40 mm.)"""
    if _silhouette_unseen(silhouette, cfg) is None or not door.arris_mm > 0:
        return 0.0
    return door.arris_mm / math.sqrt(12.0)


def _silhouette_unseen(silhouette: float | None, cfg: LocateConfig) -> str | None:
    """Where the far arris's outer edge has less contrast than edges need (``silhouette``, grey levels, under
    ``min_contrast``), the clause that says so and what to do; else None."""
    if silhouette is None or not silhouette < cfg.min_contrast:
        return None
    return (
        f", as the far arris's outer edge hardly stands out from the background behind it (a step of "
        f"{silhouette:.1f} grey levels; edges need {cfg.min_contrast:g}); light the door's far side "
        "differently or put a background of another shade behind it, and take the image again"
    )


def _misread_strips(
    measured: float,
    door: DoorSize,
    t_tol: float,
    t_sigma: float,
    strip_shifts: dict[str, float],
    beyond: bool,
) -> tuple[q.Refusal, tuple[str, ...]] | None:
    """Where a thickness ``measured`` (mm) that misses the recipe lands on it with one or both side arrises'
    strips read the other way (``strip_shifts``, mm: :func:`strip_other_readings`), the ``uncertain``
    refusal that says so and the arrises it names; else None (a wrong door, or another cause).

    Missing the recipe: beyond the tolerance (``beyond``; then the other reading must pass the tolerance), or
    within it by more than ``MISREAD_SIGMAS`` sigmas (then the other reading must lie within as many). The image cannot
    tell such a door from one whose thickness is off by a strip's width: it is refused as uncertain, naming
    the arris and what would tell, neither sent after the wrong door nor answered. Measured, arrises as dark
    as the background through a sharp lens (`bench_arris_range.py --sets focused_dark --seed 8100 --n 32`):
    five valid doors were refused ``thickness_mismatch``, every one's other reading within 0.04 mm of the
    recipe; and one of them (seed 16125, a 1 mm rounding, every strip read at the face's level), under a
    tolerance of 3 mm, was answered 0.83 mm off in x and 0.78 mm in z at sigmas of 0.08 and 0.10 mm, its
    thickness 1.67 mm (7 sigma) thin and both side arrises' other readings 69.97 mm for 70.
    """
    keys = [k for k in ("reference", "far") if k in strip_shifts]
    subsets = [(k,) for k in keys] + ([tuple(keys)] if len(keys) == 2 else [])
    readings = {sub: measured + sum(strip_shifts[k] for k in sub) for sub in subsets}
    fits = [
        sub
        for sub, t in readings.items()
        if (
            q.check_thickness(t, door.thickness_mm, t_tol, sigma=t_sigma) is None
            if beyond
            else abs(t - door.thickness_mm) <= MISREAD_SIGMAS * t_sigma
        )
    ]
    if not fits:
        return None
    sub = min(fits, key=lambda k: abs(readings[k] - door.thickness_mm))
    other = readings[sub]
    both = len(sub) == 2
    names = (
        "both side arrises are"
        if both
        else f"the {'reference-face' if sub[0] == 'reference' else 'far'} arris is"
    )
    shows = (
        "their strips show one step each, which is a strip's"
        if both
        else "its strip shows one step, which is the strip's"
    )
    doubt = "; the door's place along X is as much in doubt" if "reference" in sub else ""
    return (
        q.Refusal(
            "uncertain",
            (
                f"the door's thickness cannot be checked: it measures {measured:.2f} mm against "
                f"{door.thickness_mm:.2f} mm (tolerance {t_tol:g} mm)"
                if beyond
                else f"the door's thickness misses the recipe by more than its doubt: it measures {measured:.2f} +- "
                f"{t_sigma:.2f} mm against {door.thickness_mm:.2f} mm"
            )
            + f", or {other:.2f} mm if {names} read the other way: {shows} outer border "
            "(a strip as bright as the hinge face) or its inner border (a strip as dark as the background), and "
            f"the image cannot tell which{doubt}; light the arrises so that they stand apart from both the face "
            "and the background, or check that the right door is in the fixture",
        ),
        sub,
    )


def thickness_diagnostics(
    r: Refined,
    door: DoorSize,
    cfg: LocateConfig,
    sigma_mm: float,
    uncertain: bool,
    other: float | None,
    silhouette: float | None,
    bottom_end: float | None = None,
) -> dict:
    """The thickness check's figures for the answer's diagnostics (mm): the measured and the expected
    thickness, their difference, the tolerance, the reported standard uncertainty ``sigma_mm``, whether the
    check found it ``uncertain``, whether the far face was in view, the other reading ``other`` where there
    is one, the far silhouette's contrast (grey levels) and the door's bottom end's level where it told the
    far face's readings apart (0 the hinge face's, 1 the background's: :mod:`doorloc.vision.bottom_end`)."""
    pose = r.pose
    return {
        "measured_mm": round(pose.thickness_mm, 4),
        "expected_mm": door.thickness_mm,
        "difference_mm": round(pose.thickness_mm - door.thickness_mm, 4),
        "tolerance_mm": cfg.thickness_tolerance_mm,
        "sigma_mm": round(sigma_mm, 5),
        "uncertain": uncertain,
        "far_face_in_view": r.far_beside,
        "other_reading_mm": round(other, 4) if other is not None else None,
        "far_silhouette_contrast": round(silhouette, 2) if silhouette is not None else None,
        "bottom_end_level": round(bottom_end, 3) if bottom_end is not None else None,
    }
