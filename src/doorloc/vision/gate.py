"""The gate of locate: from the refined state, the response check and the lines' doubts, the answer or a
refusal with its reason (:func:`gate_and_answer`). It decides; the pixels it reads are only those that tell
a pattern (a calibration board) from a door whose edges failed, and flat patches beside the edges whose
noise says whether the camera sharpens its images.

The refusal codes it gives: ``edge_missing``, ``edge_not_straight``, ``corner_hidden``, ``overexposed``,
``sharpened``, ``outside_envelope``, ``thickness_mismatch``, ``uncertain``, ``not_a_door``
(:mod:`doorloc.vision.quality` holds the checks and their messages).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.vision import quality as q
from doorloc.vision.config import LocateConfig
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.lines import RectangleFit
from doorloc.vision.region import EDGE_NAMES, HUMAN, SearchRegion
from doorloc.vision.response import ResponseFit
from doorloc.vision.result import LineQuality, LocateResult, PoseUncertainty
from doorloc.vision.sampling import oriented
from doorloc.vision.state import EdgeDoubts, Refined, ResponseCheck
from doorloc.vision.strip_response import CellDisputed
from doorloc.vision.uncertainty import (
    Budget,
    EdgeModelTerms,
    LineLever,
    calibration_pose_sigma,
    propagate,
)

__all__ = ["PATTERN", "gate_and_answer"]


PATTERN = q.Refusal(
    "not_a_door",
    "a regular pattern (a calibration board?) is in view instead of a door; "
    "remove it and place a door in the fixture",
)


def gate_and_answer(
    name: str,
    door: DoorSize,
    cfg: LocateConfig,
    region: SearchRegion,
    check: ResponseCheck,
    doubts: EdgeDoubts,
    plane,
    s8: float,
) -> LocateResult:
    """The gate: the answer, or the refusal with its reason, from the refined edges, the response check and
    the lines' doubts. (It reads the pixels only to tell a pattern from a door where the edges failed.)

    The checks in the order they are weighed (the first that refuses is the answer's reason, unless a pose
    outside the envelope or a pattern in view explains it better, :func:`_first_refusal`): each line's
    support and straightness, the corner's support, overexposure and sharpening, the envelope, the
    thickness, the corner's and the pose's uncertainty."""
    r, cell = check.refined, check.cell
    model, figures, disputed = doubts.model, doubts.figures, doubts.response_disputed
    fit, pose = r.fit, r.pose
    diagnostics = _fit_diagnostics(r, region, door, figures)
    lines, refusals = _line_checks(r, region, model, cfg)
    refusals += _corner_support(r, region, cfg, diagnostics)
    refusals += _exposure_checks(plane, s8, r, cfg, diagnostics)
    refusals.append(
        q.check_envelope(
            pose.x_mm, pose.z_mm, pose.yaw_deg, cell.envelope, cfg.envelope_margin_mm, cfg.envelope_margin_deg
        )
    )
    other_mm, other = _other_reading(r, cfg.thickness_tolerance_mm)
    # Standard uncertainty of the thickness: the two arris offsets' noise, and beside a visible far face
    # what its model leaves in doubt (a band narrower than the blur is hard to tell from the arris).
    # The two arrises' response doubts share their cause (one camera exponent moves both edges outwards
    # or both inwards, and the thickness by their sum): they add, the rest in quadrature. (Added in
    # quadrature, the effects fixtures' thicknesses, a 2.2 camera in a cell of 1.0, were 0.08-0.12 mm off
    # with 78 % of them beyond 2 sigma.)
    budget = _budget(cell, cfg, region, r, model, other_mm if other is not None else None)
    silhouette = _far_silhouette_contrast(r)
    t_refusals, unverified, t_uncertain = _thickness_check(
        r, door, cfg, budget.thickness_mm, other, silhouette, _strip_other_readings(r)
    )
    # Under ``thickness_check: report`` a thickness the image cannot verify is said in the answer, not refused
    # (a thickness that is wrong at confidence is refused under either policy: it is in ``t_refusals``).
    refusals += t_refusals + (unverified if cfg.thickness_check == "refuse" else [])
    refusals += [_corner_sigma_check(fit, cfg, diagnostics), _response_disputed(disputed, cell)]
    diagnostics["thickness_check"] = _thickness_diagnostics(
        r, door, cfg, budget.thickness_reported_mm, t_uncertain, other, silhouette
    )
    unc = PoseUncertainty(x_mm=budget.x_mm, z_mm=budget.z_mm, yaw_deg=budget.yaw_deg)
    diagnostics["uncertainty_terms"] = {k: [round(v, 6) for v in t] for k, t in budget.groups.items()}
    diagnostics["uncertainty_budget"] = [t.as_dict() for t in budget.terms]
    refusals.append(pose_refusal := _pose_check(unc, budget.groups, model, check.response, cfg))
    first = _with_uncertain_pose(
        _first_refusal(refusals, r, plane, s8, cfg), unverified, pose_refusal, unc, cfg
    )
    if first is not None:
        diagnostics["measured"] = {
            "x_mm": pose.x_mm,
            "z_mm": pose.z_mm,
            "yaw_deg": pose.yaw_deg,
            "thickness_mm": pose.thickness_mm,
        }
        diagnostics["all_refusals"] = [x.code for x in refusals if x is not None]
        return LocateResult.refusal(name, first.code, first.message, lines=lines, diagnostics=diagnostics)
    return LocateResult(
        image=name,
        ok=True,
        x_mm=pose.x_mm,
        z_mm=pose.z_mm,
        yaw_deg=pose.yaw_deg,
        thickness_mm=pose.thickness_mm,
        scale_mm_per_px=pose.scale_mm_per_px,
        corner_px=[float(pose.corner_px[0]), float(pose.corner_px[1])],
        uncertainty=unc,
        thickness_verified=not unverified,
        thickness_unverified_reason=unverified[0].message if unverified else None,
        lines=lines,
        diagnostics=diagnostics,
    )


def _with_uncertain_pose(
    first: q.Refusal | None,
    unverified: list[q.Refusal],
    pose: q.Refusal | None,
    unc: PoseUncertainty,
    cfg: LocateConfig,
) -> q.Refusal | None:
    """The answer's reason ``first``; where it is a thickness the image cannot verify (``unverified``) and the
    pose is refused as too uncertain besides (``pose``), both said. The thickness's reason asks to move the
    door or check it, which does not help a pose too uncertain (``bench_surfaces.py --sets combined``: every
    door refused for its thickness was refused for its pose as well, and the operator read only the
    thickness)."""
    if first is None or not unverified or first is not unverified[0] or pose is None:
        return first
    return q.Refusal(
        first.code,
        f"{first.message}; the pose is uncertain as well (x {unc.x_mm:.3f} mm, z {unc.z_mm:.3f} mm, yaw "
        f"{unc.yaw_deg:.3f} deg, 1 sigma; the cell allows {cfg.max_uncertainty_mm:g} mm, "
        f"{cfg.max_uncertainty_deg:g} deg)",
    )


def _arris_clipped(r: Refined, cfg: LocateConfig) -> q.Refusal | None:
    """The arris strips' white clipping (:func:`doorloc.vision.quality.check_arris_clipped`), each strip named
    by its edge."""
    if not r.arris_fits:
        return None
    clipped = {HUMAN[k]: strip.clipped_share for k, (strip, _) in r.arris_fits.items()}
    return q.check_arris_clipped(clipped, cfg.max_clipped_arris_fraction)


#: the flat patches :func:`_noise_scale_ratio` reads beside each line: their length along the edge and depth
#: across it, and their distance from the edge's points (beyond a 3 mm arris strip and the blur), px
NOISE_PATCH_PX = (128, 48)
NOISE_PATCH_GAP_PX = 24


def _exposure_checks(plane, s8: float, r: Refined, cfg: LocateConfig, diagnostics: dict) -> list:
    """What the camera made of the door's light: the hinge face or an arris strip clipped at white, and a
    camera that sharpens its images (:func:`_sharpened`)."""
    bright = np.concatenate([r.samples[k].bright[r.fit.weights[k] > 0] for k in EDGE_NAMES])
    return [q.check_overexposed(bright), _arris_clipped(r, cfg), _sharpened(plane, s8, r, cfg, diagnostics)]


def _sharpened(plane, s8: float, r: Refined, cfg: LocateConfig, diagnostics: dict) -> q.Refusal | None:
    """The sharpening check (``locate.min_noise_scale_ratio``; 0: off), its figure into
    ``diagnostics["noise_scale_ratio"]``."""
    if cfg.min_noise_scale_ratio <= 0:
        return None
    ratio = _noise_scale_ratio(plane, s8, r)
    diagnostics["noise_scale_ratio"] = None if ratio is None else round(ratio, 3)
    return q.check_sharpened(ratio, cfg.min_noise_scale_ratio)


def _noise_scale_ratio(plane, s8: float, r: Refined) -> float | None:
    """The least of :func:`doorloc.vision.quality.noise_scale_ratio` over the door's two sides: patches
    beside the middle of each line's edge points, pooled per side (dark and bright). Texture and a stray
    edge in a patch raise its ratio (they hide sharpening there; they never make it)."""
    sides: dict[bool, list[np.ndarray]] = {False: [], True: []}
    length, depth = NOISE_PATCH_PX
    for k in EDGE_NAMES:
        s = r.samples[k]
        ok = (r.fit.weights[k] > 0) & np.isfinite(s.along)
        scan, along = s.scan[ok], s.along[ok]
        if scan.size < 8:
            continue
        centre = 0.5 * (float(scan.min()) + float(scan.max()))
        mid = np.abs(scan - centre) <= length / 2
        if not mid.any():
            continue
        P = oriented(plane, s.axis)
        s0, s1 = int(scan[mid].min()), int(scan[mid].max()) + 1
        lo, hi = int(math.floor(along[mid].min())), int(math.ceil(along[mid].max()))
        step = s.step[ok]
        bright_after = float(step.sum(where=np.isfinite(step))) > 0  # the bright side at larger ``along``
        for after in (False, True):
            a0 = hi + NOISE_PATCH_GAP_PX if after else lo - NOISE_PATCH_GAP_PX - depth
            if 0 <= a0 and a0 + depth <= P.shape[0] and 0 <= s0 and s1 <= P.shape[1]:
                sides[after == bright_after].append(P[a0 : a0 + depth, s0:s1])
    ratios = [x for x in (q.noise_scale_ratio(sides[b], s8) for b in (False, True)) if x is not None]
    return min(ratios) if ratios else None


def _fit_diagnostics(r: Refined, region: SearchRegion, door: DoorSize, figures: dict[str, Any]) -> dict:
    """The answer's first diagnostics: the refine stage's blur and window (px), the hinge-face plane's and the
    edges' depths (mm), the line fit's residual scale (mm) and yaw doubt (degrees), the expected thickness
    (mm) and the edge models' ``figures``."""
    fit = r.fit
    return {
        "blur_px": round(r.blur_px, 3),
        "window_half_px": r.half,
        "face_y_mm": region.face_y,
        "edge_depth_y_mm": region.edge_depth_y,
        "fit_scale_mm": fit.scale,
        "yaw_sigma_deg": math.degrees(fit.angle_sigma_rad),
        "thickness_expected_mm": door.thickness_mm,
        **figures,
    }


def _thickness_diagnostics(
    r: Refined,
    door: DoorSize,
    cfg: LocateConfig,
    sigma_mm: float,
    uncertain: bool,
    other: float | None,
    silhouette: float | None,
) -> dict:
    """The thickness check's figures for the answer's diagnostics (mm): the measured and the expected
    thickness, their difference, the tolerance, the reported standard uncertainty ``sigma_mm``, whether the
    check found it ``uncertain``, whether the far face was in view, the other reading ``other`` where there
    is one and the far silhouette's contrast (grey levels)."""
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
    }


def _line_checks(
    r: Refined, region: SearchRegion, model: EdgeModelTerms, cfg: LocateConfig
) -> tuple[list[LineQuality], list]:
    """Each line's figures (:class:`doorloc.vision.result.LineQuality`) and its check (None where it passes)."""
    samples, fit, pose, far_beside = r.samples, r.fit, r.pose, r.far_beside
    lines, refusals = [], []
    for k in EDGE_NAMES:
        s = samples[k]
        n_s = int(s.scan.size)
        # (the step that located each point: on an arris line with a faint face step, its strip's border)
        located = s.located_contrast(region.layouts[k].polarity, cfg.min_contrast)
        n_i, mean_square, contrast, noise = q.line_figures(fit.weights[k], fit.residuals[k], located, s.noise)
        rms_mm = math.sqrt(mean_square) if n_i else float("nan")
        rms_px = rms_mm / pose.scale_mm_per_px
        # what the edge model leaves in doubt (floor, texture, far-face model...), on top of the noise
        extra = {"model_sigma_mm": round(model.line_sigma_px(k) * pose.scale_mm_per_px, 6)}
        for term, key in (("arris", "arris_correction_sigma_mm"), ("response", "response_sigma_mm")):
            doubt = model.offset_px(k, term)
            if doubt is not None:
                extra[key] = round(doubt * pose.scale_mm_per_px, 5)
        lines.append(
            LineQuality(
                name=k,
                n_points=n_s,
                n_inliers=n_i,
                rms_residual_px=round(rms_px, 4),
                rms_residual_mm=round(rms_mm, 5),
                contrast=round(contrast, 1),
                noise=round(noise, 2) if n_i else None,
                offset_sigma_mm=round(fit.offset_sigma[k], 5),
                **extra,
            )
        )
        # Beside a visible far face the far arris only measures the thickness (it takes no part in the
        # pose): a looser straightness check.
        loose = k == "far" and far_beside
        refusals.append(
            q.check_line(
                HUMAN[k],
                n_s,
                n_i,
                rms_px,
                contrast,
                q.LineLimits(
                    cfg.min_inliers,
                    cfg.min_inlier_fraction * (0.5 if loose else 1.0),
                    cfg.max_rms_residual_px * (2.0 if loose else 1.0),
                    cfg.min_contrast,
                ),
            )
        )
    return lines, refusals


def _corner_support(r: Refined, region: SearchRegion, cfg: LocateConfig, diagnostics: dict) -> list:
    """The checks of the points next to the corner on the bottom end and the reference arris."""
    samples, fit, pose, corner_px = r.samples, r.fit, r.pose, r.pose.corner_px
    refusals = []
    for k in ("bottom", "reference"):
        s = samples[k]
        lay = region.layouts[k]
        c_scan = corner_px[0] if lay.axis == "col" else corner_px[1]
        near = np.abs(s.scan - c_scan) <= cfg.corner_zone_px
        n = int(np.count_nonzero(near))
        fits = (fit.weights[k] > 0) | (
            np.abs(fit.residuals[k]) <= cfg.corner_tolerance_px * pose.scale_mm_per_px
        )
        frac = int(np.count_nonzero(fits[near])) / n if n else 0.0
        diagnostics[f"corner_support_{k}"] = round(frac, 3)
        refusals.append(q.check_corner_support(HUMAN[k], frac, n, cfg.min_corner_support))
    return refusals


def _other_reading(r: Refined, t_tol: float) -> tuple[float, float | None]:
    """How far a far face's other reading lies, mm, and that reading of the thickness where it is weighed."""
    pose, far_fit, far_beside = r.pose, r.far_fit, r.far_beside
    # A far face whose band looks like the background or like the hinge face reads two ways, a band's width
    # apart (edges.FarFaceFit.other_reading_px), and the image cannot tell which: the check takes the reading
    # nearer the recipe (a wrong door passes only where its other reading lands on the recipe's thickness),
    # and the reported sigma reaches the other reading at 2 sigma. Readings more than twice the tolerance
    # apart are not weighed (the fitted one is judged alone, as without a band): a band that wide is seen
    # (on bench_surfaces' grain, hard and thin sets, 60 doors each, every fitted reading whose other lay
    # 2.6-20 mm off was the door's; the two wrong ones were read beside bands of 0.6-1.2 px, 0.4-0.8 mm).
    other_mm = far_fit.other_reading_px * pose.scale_mm_per_px if far_beside and far_fit is not None else 0.0
    other = pose.thickness_mm + other_mm if 0.0 < abs(other_mm) <= 2.0 * t_tol else None
    return other_mm, other


def _far_silhouette_contrast(r: Refined) -> float | None:
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
#: a thickness within the tolerance that misses the recipe by more than this many of its sigmas, where a side
#: arris's other reading lands within as many, is that arris's misreading as likely as a door off its recipe
MISREAD_SIGMAS = 3.0


def _strip_other_readings(r: Refined) -> dict[str, float]:
    """Per side arris whose strip the fit read as one plain step: how far its other reading moves the
    thickness, mm (positive: thicker).

    A strip at the hinge face's level and one at the background's both show one step, the first at the
    strip's outer border and the second at its inner border, a strip's width apart, and the profiles fit
    both alike: only the strip's radiance prior (:data:`doorloc.vision.strip_prior.STRIP_RADIANCE`) chose
    between them. A deficit ``d`` places the outer border ``d`` strip widths outwards from where a plain step
    would, so the other reading (deficit 1 for a strip read at the face's level, 0 for one read at the
    background's) moves the edge by the deficits' difference times the width. The far arris beside a seen
    far face is left out (its band's own other reading is :func:`_other_reading`'s)."""
    shifts: dict[str, float] = {}
    for k in ("reference", "far"):
        if k not in r.arris_fits or (k == "far" and r.far_beside):
            continue
        strip, band_px = r.arris_fits[k]
        d = strip.model_deficit
        if not math.isfinite(d) or PLAIN_STEP_DEFICIT < d < 1.0 - PLAIN_STEP_DEFICIT:
            continue  # a strip with a level between: two steps, no other reading
        other_deficit = 1.0 if d < 0.5 else 0.0
        shifts[k] = (other_deficit - strip.deficit) * band_px * r.pose.scale_mm_per_px
    return shifts


def _thickness_check(
    r: Refined,
    door: DoorSize,
    cfg: LocateConfig,
    t_sigma: float,
    other: float | None,
    silhouette: float | None = None,
    strip_shifts: dict[str, float] | None = None,
) -> tuple[list, list, bool]:
    """The thickness's checks against the recipe: the refusals that stand under either policy, those of a
    thickness the image cannot verify (refused under ``refuse``, reported under ``report``), and whether the
    thickness is uncertain. ``silhouette``: the far arris's outer border's contrast, grey levels
    (:func:`_far_silhouette_contrast`); below the edges' ``min_contrast`` the reason names it. ``strip_shifts``:
    the side arrises' other readings (:func:`_strip_other_readings`), weighed where the fitted thickness misses
    the recipe."""
    pose, far_beside, t_tol = r.pose, r.far_beside, cfg.thickness_tolerance_mm
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
    if mismatch is not None:
        return [mismatch], [], True
    if abs(nearest - door.thickness_mm) + 3.0 * t_sigma <= t_tol:
        return [], [], False
    measured = (
        f"the door's thickness cannot be checked: it measures {nearest:.2f} +- {3 * t_sigma:.2f} mm against "
        f"{door.thickness_mm:.2f} mm (tolerance {t_tol:g} mm)"
    )
    if silhouette is not None and silhouette < cfg.min_contrast:
        why = (
            f", as the far arris's outer edge hardly stands out from the background behind it (a step of "
            f"{silhouette:.1f} grey levels; edges need {cfg.min_contrast:g}); light the door's far side "
            "differently or put a background of another shade behind it, and take the image again"
        )
    else:
        why = (
            f"{' with its far face seen nearly edge-on' if far_beside else ''}; check the door and the "
            "recipe, or move the door a little along X and take the image again"
        )
    return [], [q.Refusal("uncertain", measured + why)], True


def _misread_strips(
    measured: float,
    door: DoorSize,
    t_tol: float,
    t_sigma: float,
    strip_shifts: dict[str, float],
    beyond: bool,
) -> tuple[q.Refusal, tuple[str, ...]] | None:
    """Where a thickness ``measured`` (mm) that misses the recipe lands on it with one or both side arrises'
    strips read the other way (``strip_shifts``, mm: :func:`_strip_other_readings`), the ``uncertain``
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


def _response_disputed(disputed: CellDisputed | None, cell: Cell) -> q.Refusal | None:
    """Where the door's rounded or chamfered strips rule out the cell's own camera exponent (the doubts
    stage's :class:`doorloc.vision.strip_response.CellDisputed`): the cell's ``camera.response_gamma`` is
    wrong for this camera, and an answer resting on it is off by what the wrong exponent moves the arrises
    (arris bench seed 9109, a cell of 2.40 for a camera of 1.11: 0.165 mm in x, at 1.8 of its sigmas)."""
    if disputed is None:
        return None
    seen = (
        "the rounded arrises' shading fits a matt surface"
        if disputed.evidence == "arcs"
        else "the chamfers' profiles fit the image"
    )
    return q.Refusal(
        "uncertain",
        f"the arrises disagree with the cell's camera response (camera.response_gamma {cell.response_gamma:g}): "
        f"read with it, {seen} {disputed.cell_over_best:.2f} times worse than with {disputed.best_gamma:g}; "
        "measure the response once (doorloc calibrate prints it from the chessboard photographs) and put it "
        "in the cell file",
    )


def _corner_sigma_check(fit: RectangleFit, cfg: LocateConfig, diagnostics: dict) -> q.Refusal | None:
    """The check of the corner's standard error from the line offsets."""
    sig = math.hypot(fit.offset_sigma["reference"], fit.offset_sigma["bottom"])
    diagnostics["corner_sigma_mm"] = sig
    if sig > cfg.max_sigma_mm:
        return q.Refusal(
            "uncertain",
            f"the corner is uncertain to {sig:.3f} mm (limit {cfg.max_sigma_mm} mm): "
            "the edges are too noisy; check focus, lighting and exposure",
        )
    return None


def _pose_check(
    unc: PoseUncertainty,
    terms: dict[str, tuple[float, float, float]],
    model: EdgeModelTerms,
    response: ResponseFit | None,
    cfg: LocateConfig,
) -> q.Refusal | None:
    """The check of the pose's uncertainty against the cell's limits, naming the term that weighs most."""
    if (
        unc.x_mm > cfg.max_uncertainty_mm
        or unc.z_mm > cfg.max_uncertainty_mm
        or unc.yaw_deg > cfg.max_uncertainty_deg
    ):
        worst = max(
            terms,
            key=lambda k: max(
                terms[k][0] / cfg.max_uncertainty_mm,
                terms[k][1] / cfg.max_uncertainty_mm,
                terms[k][2] / cfg.max_uncertainty_deg,
            ),
        )
        hint = _UNCERTAIN_HINT[worst]
        if worst == "edge_model":
            # the unchecked response or the unmeasured optics is the largest doubt of a pose line: say so,
            # and what lifts it
            big = [model.largest_source(k, among=_MODEL_REPORTED) for k in ("bottom", "reference")]
            if "response" in big and response is None:
                hint = _UNCERTAIN_HINT["response_unmeasured"]
            elif "optics" in big:
                hint = _UNCERTAIN_HINT["optics_unmeasured"]
        return q.Refusal(
            "uncertain",
            f"the pose is uncertain to x {unc.x_mm:.3f} mm, z {unc.z_mm:.3f} mm, "
            f"yaw {unc.yaw_deg:.3f} deg (1 sigma; the cell allows {cfg.max_uncertainty_mm:g} mm, "
            f"{cfg.max_uncertainty_deg:g} deg), mostly from the {worst.replace('_', ' ')}; " + hint,
        )
    return None


def _first_refusal(refusals: list, r: Refined, plane, s8: float, cfg: LocateConfig) -> q.Refusal | None:
    """The answer's reason among the refusals: the first, unless a pose outside the envelope explains broken
    edges, or broken edges are a regular pattern in view."""
    samples = r.samples
    first = next((r for r in refusals if r is not None), None)
    if first is not None and first.code in ("edge_not_straight", "edge_missing", "corner_hidden"):
        # A pose outside the envelope explains broken edges best (the door lies beyond the region).
        env = next((r for r in refusals if r is not None and r.code == "outside_envelope"), None)
        first = env or first
    if first is not None and first.code in ("edge_not_straight", "edge_missing"):
        band = _rows_across(plane, s8, samples["reference"], samples["far"])
        if band is not None and q.looks_like_pattern(band, 4 * cfg.min_contrast):
            first = PATTERN
    return first


_UNCERTAIN_HINT = {
    "response_unmeasured": "the camera response could not be checked on this image (diagnostics "
    "camera_response.unchecked_because says why: every edge an arris, edges sharper than half a pixel, or a "
    "door square to the camera), and "
    "the cell's camera.response_gamma is taken as known only within the factor "
    "locate.response_unmeasured_factor; measure the response once (doorloc calibrate prints it from the "
    "chessboard photographs, with the factor they allow; or an image of a plain-edged door in this cell: its "
    "answer's diagnostics camera_response.fitted), put it in the cell file and set "
    "locate.response_unmeasured_factor to what the measurement allows",
    "optics_unmeasured": "the camera's optics were not measured, and the cell takes every edge as known only "
    "within locate.optics_edge_sigma_px; measure them once (doorloc check-model --boards on the calibration's "
    "chessboard photographs writes the camera's photometric model, with what it leaves on real edges) and "
    "point the cell's camera.calibration at the file it writes",
    "fit": "the edges are too noisy; check focus, lighting and exposure",
    "edge_model": "the door's edges do not look like clean steps (strong grain or marks along an edge, an arris or "
    "a camera response the cell does not describe); check the cell's door and camera settings",
    "calibration": "the camera calibration is too uncertain here; calibrate again with views covering the door's corner",
    "cell": "the cell's camera placement is too uncertain; run the cell check again",
}


#: the doubts a line's edge model reports besides the texture beside it (the texture of a pose line is its
#: own term; which of these is largest names the hint of an uncertain pose)
_MODEL_REPORTED = ("far_face", "jpeg", "arris", "response", "camera", "optics")


def _budget(
    cell: Cell,
    cfg: LocateConfig,
    region: SearchRegion,
    r: Refined,
    model: EdgeModelTerms,
    other_mm: float | None,
) -> Budget:
    """The answer's uncertainty (:func:`doorloc.vision.uncertainty.propagate`): the lines' levers from their
    inlier points, the calibration's and the cell's terms.

    ``far_votes``: whether the far arris voted on the door's direction in the joint fit (it does unless a
    far face is beside it); its tilt then moves the yaw as the others' do. ``other_mm``: how far a far
    face's other reading lies, where it is weighed.
    """
    samples, fit, pose, far_votes = r.samples, r.fit, r.pose, not r.far_beside
    sc = pose.scale_mm_per_px
    levers = {}
    for k in ("reference", "bottom", "far") if far_votes else ("reference", "bottom"):
        s = samples[k]
        inl = (fit.weights[k] > 0) & np.isfinite(s.along)
        corner_scan = pose.corner_px[0] if s.axis == "col" else pose.corner_px[1]
        levers[k] = LineLever.of_points(s.scan[inl], corner_scan, sc)
    cal_t = calibration_pose_sigma(
        cell.posed_camera,
        region.face_map.depth_y,
        pose.corner_px,
        pose.yaw_deg,
        cell.calibration_covariance,
        cell.calibration_covariance_names,
        cfg.calibration_sigma_px,
        sc,
    )
    camera = {"calibration": cal_t, "cell": (cfg.cell_sigma_mm, cfg.cell_sigma_mm, cfg.cell_sigma_deg)}
    return propagate(model, fit.offset_sigma, fit.angle_sigma_rad, levers, sc, camera, other_mm)


def _rows_across(plane, s8: float, ref: EdgeSamples, far: EdgeSamples) -> np.ndarray | None:
    """Grey profiles (0-255) across the door between and beyond its two arrises, for the pattern check."""
    if ref.scan.size == 0:
        return None
    P = oriented(plane, ref.axis)
    a = np.concatenate([ref.along[np.isfinite(ref.along)], far.along[np.isfinite(far.along)]])
    if a.size == 0:
        return None
    lo, hi = int(max(a.min() - 150, 0)), int(min(a.max() + 150, P.shape[0] - 1))
    return P[lo : hi + 1, ref.scan[::8]].T.astype(np.float32) * s8
