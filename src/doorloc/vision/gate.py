"""The gate of locate: from the refined state, the response check and the lines' doubts, the answer or a
refusal with its reason (:func:`gate_and_answer`). It decides; the pixels it reads are only those that tell
a pattern (a calibration board) from a door whose edges failed, and flat patches beside the edges whose
noise says whether the camera sharpens its images.

The refusal codes it gives: ``edge_missing``, ``edge_not_straight``, ``corner_hidden``, ``overexposed``,
``sharpened``, ``outside_envelope``, ``thickness_mismatch``, ``uncertain``, ``not_a_door``, ``arris_mismatch``
(:mod:`doorloc.vision.quality` holds the checks and their messages).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.pose import DoorPose
from doorloc.vision import quality as q
from doorloc.vision.bottom_end import DoorInView, settled_by_bottom_end
from doorloc.vision.config import LocateConfig
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.lines import RectangleFit, own_scatter_weights
from doorloc.vision.luminance import LuminancePlane
from doorloc.vision.region import EDGE_NAMES, HUMAN, SearchRegion
from doorloc.vision.response import ResponseFit
from doorloc.vision.result import LineQuality, LocateResult, PoseUncertainty
from doorloc.vision.sampling import oriented
from doorloc.vision.side_patches import side_patches
from doorloc.vision.state import EdgeDoubts, Refined, ResponseCheck
from doorloc.vision.strip_response import CellDisputed
from doorloc.vision.thickness_gate import (
    far_silhouette_contrast,
    other_reading,
    reported_budget,
    strip_other_readings,
    thickness_check,
    thickness_diagnostics,
)
from doorloc.vision.uncertainty import (
    Budget,
    EdgeModelTerms,
    LineLever,
    calibration_pose_sigma,
    propagate,
)
from doorloc.vision.untold_arris import untold_arris_check

__all__ = ["PATTERN", "gate_and_answer", "uncertain_pose_words", "within_pose_limits"]


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
    lum: LuminancePlane,
) -> LocateResult:
    """The gate: the answer, or the refusal with its reason, from the refined edges, the response check and
    the lines' doubts (it reads pixels only to tell a pattern from a door, an untold arris's strip, a far
    face's readings apart, and what the camera made of the door's light). The checks in the order they are
    weighed (the first that refuses is the answer's reason, unless a pose outside the envelope or a pattern
    in view explains it better, :func:`_first_refusal`): an arris strip the recipe does not give, each line's
    support and straightness, the corner's support, overexposure and sharpening, an arris strip read two ways
    or one that took its edge, the envelope, the thickness, the corner's and the pose's uncertainty."""
    r, cell = check.refined, check.cell
    plane, s8 = lum.plane, lum.scale_to_8bit
    model, figures, disputed = doubts.model, doubts.figures, doubts.response_disputed
    fit, pose = r.fit, r.pose
    diagnostics = _fit_diagnostics(r, region, door, figures)
    lines, refusals = _line_checks(r, region, model, cfg)
    refusals.insert(0, untold_arris_check(plane, r, door, cell, cfg, diagnostics))
    refusals += _corner_support(r, region, cfg, diagnostics)
    refusals += _exposure_checks(lum, check, region, cfg, diagnostics)
    took = q.check_strips_took_their_edge({k: f.blur_px for k, (f, _) in r.arris_fits.items()}, HUMAN)
    refusals += _strips_read_twice(r, cfg) + [v for k, v in took.items() if k != "far"]
    refusals.append(
        q.check_envelope(
            pose.x_mm, pose.z_mm, pose.yaw_deg, cell.envelope, cfg.envelope_margin_mm, cfg.envelope_margin_deg
        )
    )
    other_mm, other, bottom_end = _other_reading_seen(plane, s8, cell, door, r, cfg)
    # Standard uncertainty of the thickness: the two arris offsets' noise, and beside a visible far face
    # what its model leaves in doubt (a band narrower than the blur is hard to tell from the arris).
    # The two arrises' response doubts share their cause (one camera exponent moves both edges outwards
    # or both inwards, and the thickness by their sum): they add, the rest in quadrature. (Added in
    # quadrature, the effects fixtures' thicknesses, a 2.2 camera in a cell of 1.0, were 0.08-0.12 mm off
    # with 78 % of them beyond 2 sigma.)
    budget = _budget(cell, cfg, region, r, model, other_mm if other is not None else None)
    silhouette = far_silhouette_contrast(r)
    t_hint = _thickness_hint(budget, check.response)
    t_refusals, unverified, t_uncertain = thickness_check(
        r, door, cfg, budget.thickness_mm, other, silhouette, strip_other_readings(r), t_hint, took.get("far")
    )
    # Under ``thickness_check: report`` a thickness the image cannot verify is said in the answer, not refused
    # (a thickness that is wrong at confidence is refused under either policy: it is in ``t_refusals``).
    refusals += t_refusals + (unverified if cfg.thickness_check == "refuse" else [])
    refusals += [_corner_sigma_check(fit, cfg, diagnostics), _response_disputed(disputed, cell)]
    budget = reported_budget(budget, door, cfg, silhouette, t_uncertain)
    diagnostics["thickness_check"] = thickness_diagnostics(
        r, door, cfg, budget.thickness_reported_mm, t_uncertain, other, silhouette, bottom_end
    )
    unc = PoseUncertainty(x_mm=budget.x_mm, z_mm=budget.z_mm, yaw_deg=budget.yaw_deg)
    diagnostics["uncertainty_terms"] = {k: [round(v, 6) for v in t] for k, t in budget.groups.items()}
    diagnostics["uncertainty_budget"] = [t.as_dict() for t in budget.terms]
    cause = _pose_cause(budget.groups, model, check.response, cfg)
    refusals.append(pose_refusal := _pose_check(unc, cause, cfg))
    first = _with_uncertain_pose(
        _first_refusal(refusals, r, plane, s8, cfg), unverified, pose_refusal, unc, cfg, cause
    )
    if first is not None:
        diagnostics["measured"] = {k: getattr(pose, k) for k in ("x_mm", "z_mm", "yaw_deg", "thickness_mm")}
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
    cause: tuple[str, str],
) -> q.Refusal | None:
    """The answer's reason ``first``; where it is a thickness the image cannot verify (``unverified``) and the
    pose is refused as too uncertain besides (``pose``), both said. The thickness's reason asks to move the
    door or check it, which does not help a pose too uncertain (``bench_surfaces.py --sets combined``: every
    door refused for its thickness was refused for its pose as well, and the operator read only the
    thickness)."""
    if first is None or not unverified or first is not unverified[0] or pose is None:
        return first
    mostly, hint = cause
    return q.Refusal(
        first.code,
        f"{first.message}; the pose is uncertain as well (x {unc.x_mm:.3f} mm, z {unc.z_mm:.3f} mm, yaw "
        f"{unc.yaw_deg:.3f} deg, 1 sigma; the cell allows {cfg.max_uncertainty_mm:g} mm, "
        f"{cfg.max_uncertainty_deg:g} deg), {mostly}" + ("" if hint in first.message else f"; {hint}"),
        # (the thickness's reason may already give the same advice)
    )


def _arris_clipped(r: Refined, cfg: LocateConfig) -> q.Refusal | None:
    """The arris strips' white clipping (:func:`doorloc.vision.quality.check_arris_clipped`), each strip named
    by its edge."""
    if not r.arris_fits:
        return None
    clipped = {HUMAN[k]: strip.clipped_share for k, (strip, _) in r.arris_fits.items()}
    return q.check_arris_clipped(clipped, cfg.max_clipped_arris_fraction)


def _other_reading_seen(
    plane, s8: float, cell: Cell, door: DoorSize, r: Refined, cfg: LocateConfig
) -> tuple[float, float | None, float | None]:
    """A far face's other reading (:func:`other_reading`: how far, mm, and the thickness it reads where it
    is weighed) and the door's bottom end's level where it was read. On a door without arrises whose band
    reads two ways, where the bottom end shows the fitted reading the other is dropped (``0.0, None``)."""
    other_mm, other = other_reading(r, door, cfg.thickness_tolerance_mm)
    far = r.far_fit
    if other is None or far is None or far.other_fitted or far.other_reading_px == 0.0 or door.arris_mm > 0:
        return other_mm, other, None
    in_view = DoorInView(
        cell.posed_camera,
        cell.face_y(door),
        DoorPose(r.pose.x_mm, r.pose.z_mm, r.pose.yaw_deg),
        door.width_mm,
    )
    settled, seen = settled_by_bottom_end(plane, s8, in_view, r.pose.thickness_mm, other, cfg.min_contrast)
    level = seen.level if seen is not None and math.isfinite(seen.level) else None
    return (0.0, None, level) if settled else (other_mm, other, level)


def _exposure_checks(
    lum: LuminancePlane, check: ResponseCheck, region: SearchRegion, cfg: LocateConfig, diagnostics: dict
) -> list:
    """What the camera made of the door's light: the hinge face or an arris strip clipped at white, or at the
    clip the cell's camera model states (:func:`_at_camera_clip`), the door's bright side or a flat arris
    strip clipped below white where the image shows it (:func:`_clipped_flat`), and a camera that sharpens
    its images (:func:`_sharpened`)."""
    r, plane, s8 = check.refined, lum.plane, lum.scale_to_8bit
    bright = np.concatenate([r.samples[k].bright[r.fit.weights[k] > 0] for k in EDGE_NAMES])
    read = cfg.min_noise_scale_ratio > 0 or cfg.clipped_flat_share <= 1 or lum.clip_grey is not None
    sides = side_patches(plane, r.samples, r.fit.weights) if read else None
    strips = _strip_interiors(plane, r, region, cfg.door_brighter) if cfg.clipped_flat_share <= 1 else {}
    return [
        q.check_overexposed(bright),
        _arris_clipped(r, cfg),
        _at_camera_clip(lum, sides, r, region, cfg),
        _clipped_flat(sides, strips, s8, cfg, check, bright),
        _sharpened(sides, s8, cfg, diagnostics),
    ]


def _at_camera_clip(
    lum: LuminancePlane,
    sides: dict[bool, dict[str, np.ndarray]] | None,
    r: Refined,
    region: SearchRegion,
    cfg: LocateConfig,
) -> q.Refusal | None:
    """Where the cell's camera model states a clip below full scale (``clip_level``,
    :attr:`doorloc.vision.luminance.LuminancePlane.clip_grey`): the door's bright side at it beside any line
    (the median of its patch), or an arris strip (of 2 px or more) with two or more pixels at it on more of
    its scan lines than ``locate.max_clipped_arris_fraction`` (the strips' white check, at the camera's
    clip). Read from the stated clip, not from the image's noise, this holds where JPEG or a quiet sensor
    leave no noise to tell a clip by (:func:`_clipped_flat`)."""
    clip, at = lum.clip_grey, lum.clipped_from
    if clip is None or at is None or sides is None:
        return None
    s8 = lum.scale_to_8bit
    for k, p in sides[True].items():
        level = float(np.median(p)) * s8
        if level >= at:
            return q.Refusal(
                "overexposed",
                f"the bright side of the {HUMAN[k]} is at the camera's clip ({level:.0f} grey; the camera model "
                f"stores every light beyond {clip:.0f} there), which biases the edges; reduce the exposure time "
                "or the lighting",
            )
    strips = _strip_interiors(lum.plane, r, region, cfg.door_brighter, margin_blurs=0.0)
    clipped = {
        HUMAN[k]: float(np.mean(np.count_nonzero(p * s8 >= at, axis=1) >= 2)) for k, p in strips.items()
    }
    return q.check_arris_clipped(
        clipped, cfg.max_clipped_arris_fraction, f"the camera's clip ({clip:.0f} grey)"
    )


def _steepest_response(check: ResponseCheck) -> float:
    """The steepest camera exponent the answer's readings allow: the cell's (or the image's, where absorbed)
    and the image's own reading 2 sigma up. The steeper the response, the more it shrinks a sensor's read
    noise on the bright side against the dark one, and the flatter an unclipped bright side may be: a
    1.67 camera in a cell of 1.0 (its reading 1.65 +- 0.34, not absorbed) leaves its face at 0.2 grey of
    noise beside a dark side of 0.5, which the cell's 1.0 would read as a clip."""
    fit = check.response
    return max(check.cell.response_gamma, fit.gamma + 2.0 * fit.sigma if fit is not None else 0.0)


def _clipped_flat(
    sides: dict[bool, dict[str, np.ndarray]] | None,
    strips: dict[str, np.ndarray],
    s8: float,
    cfg: LocateConfig,
    check: ResponseCheck,
    bright: np.ndarray,
) -> q.Refusal | None:
    """The clip check (``locate.clipped_flat_share``; above 1: off,
    :func:`doorloc.vision.quality.check_clipped_flat`): each line's bright-side patch, and each flat arris
    strip's inside (:func:`_strip_interiors`), against the dark side's noise (pooled over the lines: the
    same sensor) carried through the steepest camera exponent the answer allows (:func:`_steepest_response`),
    and the brightest of the edges' bright plateaus ``bright`` (their 99th percentile; linear light on the
    0-255 scale, as the edges measure it, taken back to grey levels through the exponent they were measured
    with); the first that fails named. The noise is read only beside a patch flat enough to be a clip (most
    images have none)."""
    if sides is None or cfg.clipped_flat_share > 1:
        return None
    patches = [(f"the bright side of the {HUMAN[k]}", p) for k, p in sides[True].items()]
    patches += [(f"the arris strip along the {HUMAN[k]}", p) for k, p in strips.items()]
    flat = [(what, p) for what, p in patches if q.flat_share(p, s8) >= cfg.clipped_flat_share]
    if not flat:
        return None
    # a dark side whose noise the grey levels do not resolve (a noise-free render's) settles it cheaply
    if q.beyond_two_share(list(sides[False].values()), s8) < q.CLIP_DARK_BEYOND_TWO:
        return None
    dark = q.side_noise(list(sides[False].values()), s8)
    # the edges' plateaus are linear light: the brightest, back on the grey scale of the patches
    used = check.cell.response_gamma
    top_grey = 255.0 * (float(np.percentile(bright, 99)) / 255.0) ** (1.0 / used) if bright.size else math.inf
    gamma = _steepest_response(check)
    for what, p in flat:
        refusal = q.check_clipped_flat(
            q.side_noise([p], s8), dark, gamma, cfg.clipped_flat_share, top_grey, what
        )
        if refusal is not None:
            return refusal
    return None


#: an arris strip's inside read by the clip check (:func:`_strip_interiors`): its least width, px, and how
#: far from either border (in blur sigmas, beyond half a pixel) it starts
STRIP_INTERIOR_MIN_PX = 2
STRIP_INTERIOR_BLURS = 2.0


def _strip_interiors(
    plane, r: Refined, region: SearchRegion, door_brighter: bool, margin_blurs: float = STRIP_INTERIOR_BLURS
) -> dict[str, np.ndarray]:
    """The raw grey levels inside each arris strip, per line (N scan lines, T pixels across): the pixels
    ``margin_blurs`` blur sigmas (and half a pixel) inside both of its borders, where a chamfer's flat face
    shows its own level; none where fewer than :data:`STRIP_INTERIOR_MIN_PX` are (a small arris: the clip
    check reads it through the face's side)."""
    out: dict[str, np.ndarray] = {}
    for k, (strip, band_px) in r.arris_fits.items():
        margin = margin_blurs * strip.blur_px + 0.5
        depth = np.arange(math.ceil(margin), math.floor(float(band_px) - margin) + 1)
        s = r.samples[k]
        ok = (r.fit.weights[k] > 0) & np.isfinite(s.along)
        if depth.size < STRIP_INTERIOR_MIN_PX or not ok.any():
            continue
        side = region.layouts[k].door_side(door_brighter)
        P = oriented(plane, s.axis)
        order = np.argsort(s.scan[ok])
        rows = np.rint(s.along[ok][order, None] + side * depth[None]).astype(int)
        cols = np.broadcast_to(s.scan[ok][order, None].astype(int), rows.shape)
        inside = ((rows >= 0) & (rows < P.shape[0]) & (cols >= 0) & (cols < P.shape[1])).all(axis=1)
        if inside.sum() >= 8:
            out[k] = P[rows[inside], cols[inside]]
    return out


def _sharpened(
    sides: dict[bool, dict[str, np.ndarray]] | None, s8: float, cfg: LocateConfig, diagnostics: dict
) -> q.Refusal | None:
    """The sharpening check (``locate.min_noise_scale_ratio``; 0: off), its figures into
    ``diagnostics["noise_scale_ratio"]`` and ``["noise_scale_ratio_box2"]``."""
    if cfg.min_noise_scale_ratio <= 0 or sides is None:
        return None
    ratios = _noise_scale_ratio(sides, s8)
    diagnostics["noise_scale_ratio"] = None if ratios is None else round(ratios.pixel, 3)
    diagnostics["noise_scale_ratio_box2"] = None if ratios is None else round(ratios.box2, 3)
    return q.check_sharpened(ratios, cfg.min_noise_scale_ratio)


def _noise_scale_ratio(sides: dict[bool, dict[str, np.ndarray]], s8: float) -> q.NoiseScaleRatios | None:
    """The least of each of :func:`doorloc.vision.quality.noise_scale_ratio`'s ratios over the door's two
    sides (:func:`doorloc.vision.side_patches.side_patches`, pooled per side). Texture and a stray edge in a patch raise its ratios
    (they hide sharpening there; they never make it)."""
    read = [
        x for x in (q.noise_scale_ratio(list(sides[b].values()), s8) for b in (False, True)) if x is not None
    ]
    if not read:
        return None
    return q.NoiseScaleRatios(min(x.pixel for x in read), min(x.box2 for x in read))


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
        # Beside a visible far face the far arris only measures the thickness (it takes no part in the
        # pose): a looser straightness check, and its points judged by their own scatter about their own
        # centre where that keeps more of them than the door's common scale.
        loose = k == "far" and far_beside
        judged = (n_i, rms_px, contrast)
        if loose:
            weights, centred = own_scatter_weights(fit.residuals[k], s.valid)
            n_own, ms_own, c_own, _ = q.line_figures(weights, centred, located, s.noise)
            own = (n_own, math.sqrt(ms_own) / pose.scale_mm_per_px if n_own else float("nan"), c_own)
            judged = max(judged, own, key=lambda figures: figures[0])
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
        refusals.append(
            q.check_line(
                HUMAN[k],
                n_s,
                *judged,
                q.LineLimits(
                    cfg.min_inliers,
                    cfg.min_inlier_fraction * (0.5 if loose else 1.0),
                    cfg.max_rms_residual_px * (2.0 if loose else 1.0),
                    cfg.min_contrast,
                ),
                int(np.count_nonzero(s.valid)),
            )
        )
    return lines, refusals


def _strips_read_twice(r: Refined, cfg: LocateConfig) -> list:
    """The bottom end's and the reference arris's strips, each read at both its borders
    (:func:`doorloc.vision.quality.check_strip_read_twice`; the far arris's two readings are the thickness
    check's), weighed after the exposure checks: a strip clipped at white reads two ways too, and the
    exposure is what to change there."""
    s, share = r.pose.scale_mm_per_px, cfg.max_strip_other_border_share
    res, w = r.fit.residuals, r.fit.weights
    strips = {k: px for k, (_, px) in r.arris_fits.items() if k in ("bottom", "reference")}
    return [q.check_strip_read_twice(HUMAN[k], res[k] / s, w[k], px, share) for k, px in strips.items()]


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
        "measure the response once (doorloc calibrate prints it from the chessboard photographs, doorloc "
        "measure-light --response from six to ten doors with rounded arrises) and put it in the cell file",
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


def _pose_check(unc: PoseUncertainty, cause: tuple[str, str], cfg: LocateConfig) -> q.Refusal | None:
    """The check of the pose's uncertainty against the cell's limits, naming the term that weighs most and
    what lifts it (``cause``: :func:`_pose_cause`)."""
    if (
        unc.x_mm > cfg.max_uncertainty_mm
        or unc.z_mm > cfg.max_uncertainty_mm
        or unc.yaw_deg > cfg.max_uncertainty_deg
    ):
        return q.Refusal("uncertain", f"{uncertain_pose_words(unc, cfg)}, " + "; ".join(cause))
    return None


def within_pose_limits(unc: PoseUncertainty, cfg: LocateConfig) -> bool:
    """Whether an answer's uncertainty ``unc``, widened after the gate by another reading of the door, keeps
    within the cell's limits (``locate.max_uncertainty_mm`` in x and z, ``max_uncertainty_deg``)."""
    return max(unc.x_mm, unc.z_mm) <= cfg.max_uncertainty_mm and unc.yaw_deg <= cfg.max_uncertainty_deg


def uncertain_pose_words(unc: PoseUncertainty, cfg: LocateConfig) -> str:
    """How far the pose is uncertain and what the cell allows, as a refusal says it."""
    return (
        f"the pose is uncertain to x {unc.x_mm:.3f} mm, z {unc.z_mm:.3f} mm, "
        f"yaw {unc.yaw_deg:.3f} deg (1 sigma; the cell allows {cfg.max_uncertainty_mm:g} mm, "
        f"{cfg.max_uncertainty_deg:g} deg)"
    )


def _pose_cause(
    terms: dict[str, tuple[float, float, float]],
    model: EdgeModelTerms,
    response: ResponseFit | None,
    cfg: LocateConfig,
) -> tuple[str, str]:
    """Why a pose is too uncertain, in the operator's words: the term that weighs most against the cell's
    limits (``"mostly from the ..."``) and what lifts it."""
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
        # the largest doubt of the two pose lines, where it is one the operator can lift, is said with what
        # lifts it (the largest over both lines: an arris strip's doubt of 2 px on the reference line is not
        # named after the bottom line's doubt of unmeasured optics, a tenth of a pixel or so; nor grain at
        # an edge, 2 px, after the optics: the edge model's own words stand)
        doubts = [d for k in ("bottom", "reference") for d in model.of_line(k)]
        largest = max(doubts, key=lambda d: d.offset_px, default=None)
        hint = (_doubt_hint(largest.source, response) if largest is not None else None) or hint
    return f"mostly from the {worst.replace('_', ' ')}", hint


def _doubt_hint(source: str, response: ResponseFit | None) -> str | None:
    """What lifts an edge-model doubt of ``source`` (:data:`_UNCERTAIN_HINT`) where the operator can: the
    camera response the image could not check (``response`` None), the unmeasured optics, an arris strip
    that cannot be read closely, a JPEG's blocks, grey levels rounded without noise to dither them; else
    None."""
    if source == "response":
        return _UNCERTAIN_HINT["response_unmeasured"] if response is None else None
    key = {
        "optics": "optics_unmeasured",
        "arris": "arris",
        "jpeg": "jpeg",
        "quantisation": "quantisation",
    }.get(source)
    return _UNCERTAIN_HINT[key] if key is not None else None


#: the thickness doubts that moving the door does not lift, as :func:`_thickness_hint` names them
_THICKNESS_SOURCES = {"response": "the camera response", "arris": "the arrises"}


def _thickness_hint(budget: Budget, response: ResponseFit | None) -> str | None:
    """Where a thickness's doubt is mostly a term that moving the door does not lift, the clause that names
    it and what does (:func:`_doubt_hint`): the camera response the image could not check, or an arris
    strip that cannot be read closely; else None (the thickness check's own advice: check the door, or move
    it). On the arris bench's roundings whose thickness could not be checked (`bench_arris_range.py --n 32
    --seed 9100`) the unchecked response's doubt was most of it on seeds 9127, 11125 and 12118, the strips'
    on 11119."""
    counted = [t for t in budget.terms if t.thickness_mm is not None]
    if not counted:
        return None
    largest = max(counted, key=lambda t: float(t.thickness_mm or 0.0)).source
    hint = _doubt_hint(largest, response) if largest in _THICKNESS_SOURCES else None
    return None if hint is None else f"mostly from {_THICKNESS_SOURCES[largest]}: {hint}"


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
    "camera_response.unchecked_because says why: every edge an arris, edges sharper than half a pixel, a "
    "door square to the camera, or plateaus too quiet to read it: a camera that denoises, a JPEG of low "
    "quality), and "
    "the cell's camera.response_gamma is taken as known only within the factor "
    "locate.response_unmeasured_factor; measure the response once (doorloc calibrate prints it from the "
    "chessboard photographs, with the factor they allow; doorloc measure-light --response from six to ten "
    "doors with rounded arrises under the cell's lamp; or an image of a plain-edged door in this cell: its "
    "answer's diagnostics camera_response.fitted), put it in the cell file and set "
    "locate.response_unmeasured_factor to what the measurement allows",
    "optics_unmeasured": "the camera's optics were not measured, and the cell takes every edge as known only "
    "within locate.optics_edge_sigma_px; measure them once on the calibration's chessboard photographs "
    "(doorloc calibrate --optics writes the camera's photometric model, with what it leaves on real edges, "
    "into the calibration file, as doorloc check-model --boards does into its report's) and point the cell's "
    "camera.calibration at that file",
    "arris": "an arris strip cannot be read closely enough (its shading trades off with its border's place "
    "and the blur, most on a small arris; diagnostics arris_fit gives each strip's deficit and its sigma); check "
    "the recipe's arris size and profile, and light the arrises so that their strips stand apart from the hinge "
    "face and the background",
    "jpeg": "the image is a JPEG whose 8x8 blocks move each edge by up to a few grey levels at its quality "
    "(diagnostics jpeg_quality, jpeg_block_ratio); grab frames as PNG, or as JPEG at quality 95 or more",
    "quantisation": "the image's plateaus are quieter than half a grey level, so that its edges' grey levels "
    "are rounded with no noise to dither them (an 8-bit image of a very quiet camera, or one whose noise "
    "reduction smooths the plateaus); grab 16-bit frames (PNG), or turn the camera's noise reduction off",
    "fit": "the edges are too noisy; check focus, lighting and exposure",
    "edge_model": "the door's edges do not look like clean steps (strong grain or marks along an edge, an arris or "
    "a camera response the cell does not describe); check the cell's door and camera settings",
    "calibration": "the camera calibration is too uncertain here; calibrate again with views covering the door's corner",
    "cell": "the cell's camera placement is too uncertain; run the cell check again",
    "door_width": "the doors' widths are known only to locate.door_width_sigma_mm, and the width places the "
    "hinge face's depth; give each door's measured width with it, or measure the widths closer",
}


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
        if r.direction_votes is not None:
            levers[k] = replace(levers[k], vote=r.direction_votes.get(k, 0.0))
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
    if cfg.door_width_sigma_mm > 0:  # the width places the hinge face's depth, which no pixel shows
        dy = abs(cell.fixture.face_shift_per_width) * cfg.door_width_sigma_mm
        camera["door_width"] = (*region.face_map.depth_move(pose.corner_px, dy), 0.0)
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
