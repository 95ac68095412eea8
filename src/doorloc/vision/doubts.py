"""The doubts stage of locate: every line's edge-model doubts, each from the code that knows it.

:func:`edge_doubts` gathers them as :class:`doorloc.vision.uncertainty.LineDoubt` values: the texture beside
each edge (or the far-face model's own doubt), JPEG's block quantisation where the file was a JPEG or the
image shows it, the grey levels' rounding where no noise dithers it, what the arris correction leaves, and
the camera response's (measured, absorbed or taken on the cell's word). It reads the pixels;
:func:`doorloc.vision.uncertainty.propagate` turns the doubts into the answer's uncertainty.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from doorloc.cell import Cell
from doorloc.vision.arris_model import BLUR_DOUBT, StripFit
from doorloc.vision.config import LocateConfig
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.edge_texture import plain_edge_texture, residual_structure_tilt, unexplained_spread_px
from doorloc.vision.jpeg_blocks import block_artifact_ratio
from doorloc.vision.lines import RectangleFit, fit_image_line
from doorloc.vision.quantisation import quantisation_doubt_px, quantisation_tilt
from doorloc.vision.refine import arris_response_shifts
from doorloc.vision.region import EDGE_NAMES, SearchRegion
from doorloc.vision.response import (
    RESPONSE_PLAUSIBLE,
    ResponseFit,
    a_cameras_reading,
    edge_shifts_px,
    plateau_levels,
)
from doorloc.vision.sampling import linearizing_lut
from doorloc.vision.state import EdgeDoubts, Refined, ResponseCheck
from doorloc.vision.strip_response import AllowedEnds, StripReadings, allowed_response_ends
from doorloc.vision.texture import texture_bias
from doorloc.vision.transition import blur_without_pixel
from doorloc.vision.uncertainty import (
    CAMERA_RESPONSE,
    JPEG_BLOCK_RATIO,
    EdgeModelTerms,
    LineDoubt,
    jpeg_drift_tilt,
    jpeg_edge_doubt_px,
    jpeg_edge_grey_dn,
    jpeg_tilt_sigma,
)

__all__ = ["SIDE_BLUR_APART_PX", "edge_doubts"]


def edge_doubts(
    plane,
    s8: float,
    region: SearchRegion,
    cfg: LocateConfig,
    check: ResponseCheck,
    jpeg_quality: int = 0,
    level_8bit: float | None = None,
) -> EdgeDoubts:
    """The doubts stage: every line's edge-model doubts (:class:`doorloc.vision.uncertainty.LineDoubt`), each
    from the code that knows it: the texture beside the edge or the far-face model, JPEG's quantisation
    where the image was stored as a JPEG of ``jpeg_quality`` (its file's libjpeg quality; 0: not known to
    be a JPEG) or shows JPEG's blocks, the arris correction, the camera response. The stage that reads the
    pixels for them, so that the gate reads none. With them, the figures the diagnostics report
    (``jpeg_block_ratio``, ``jpeg_quality``, ``transition_widths_px``, ``arris_fit``), and where the door's
    rounded or chamfered strips dispute the cell's camera exponent. ``level_8bit``: one level the camera
    stored, on the 0-255 scale, where coarser than the plane's ``s8`` (a 12-bit camera's levels brought to
    16 bits: :attr:`doorloc.vision.luminance.LuminancePlane.level_8bit`), for the rounding's doubt."""
    r, cell = check.refined, check.cell
    samples, fit = r.samples, r.fit
    # An arris line's door side is its strip, whose shading the texture term would read as texture (on a
    # rounding, 0.1-0.2 mm of doubt on edges found to 0.002 mm, refused as uncertain): its texture is read
    # beyond the strip and the blur's reach.
    strips = {
        k: (
            int(math.ceil(band_px + 3.0 * strip.blur_px)),
            region.layouts[k].door_side(cfg.door_brighter),
        )
        for k, (strip, band_px) in r.arris_fits.items()
    }
    model = EdgeModelTerms(
        tuple(_edge_model_doubts(plane, r, cfg, cell, strips)),
        blur_without_pixel(r.blur_px),
    )
    figures: dict[str, Any] = {}
    blocks = block_artifact_ratio(plane, r.pose.corner_px, scale_to_8bit=s8)
    figures["jpeg_block_ratio"] = round(blocks, 3) if math.isfinite(blocks) else None
    figures["jpeg_quality"] = jpeg_quality or None
    figures["transition_widths_px"] = {
        k: round(w, 3) if math.isfinite(w) else None
        for k, w in zip(("bottom", "reference"), r.transition_widths_px, strict=True)
    }
    # a file known to be a JPEG is doubted whatever its blocks show: without noise its flat blocks are
    # flat, and the detector sees nothing while the edges still carry the quantisation
    if jpeg_quality or blocks > JPEG_BLOCK_RATIO:
        grey_dn = jpeg_edge_grey_dn(jpeg_quality)
        model = model.with_doubts(*_jpeg_doubts(samples, fit, r.pose.scale_mm_per_px, grey_dn))
    model = model.with_doubts(
        *_quantisation_doubts(samples, fit, r.half, level_8bit or s8, check.plateau_noise_dn)
    )
    if r.arris_fits:
        model = model.with_doubts(*_arris_doubts(r.arris_fits, samples, fit, r.pose.scale_mm_per_px, figures))
    model = model.with_doubts(*_optics_doubts(cell, cfg))
    disputed = None
    if check.response is not None:
        response = _response_terms(
            plane,
            r,
            cell.response_gamma,
            check.response,
            model.blur_px,
            check.absorbed,
            cfg.response_unmeasured_factor,
        )
    else:
        factor, allowed = cfg.response_unmeasured_factor, None
        readings: dict = {}  # (one door's strips read once per exponent, whatever the calls ask)

        def read_strips(gammas: list[float], scores: str) -> StripReadings:
            return arris_response_shifts(
                plane, s8, region, r, cfg, cell.response_gamma, gammas, scores, memo=readings
            )

        if factor > 1.0:
            allowed = allowed_response_ends(cell.response_gamma, factor, read_strips)
            disputed = allowed.disputed
        response = _unmeasured_response_terms(
            plane, r, cell.response_gamma, factor, model.blur_px, allowed, figures
        )
    return EdgeDoubts(model.with_doubts(*response), figures, disputed)


def _optics_doubts(cell: Cell, cfg: LocateConfig) -> list[LineDoubt]:
    """What the camera's optics may move every edge by beyond the edge model (px): one camera's error, the
    same way on every edge (its bright areas larger or smaller, its point spread off centre), so one
    correlation group. Measured where the cell carries the camera's photometric model with its held-out
    ``residual_edge_px`` (the ``camera`` source), else the cell's ``optics_edge_sigma_px`` (``optics``; a
    model that states only a clip, or a response, has measured no edges)."""
    measured = cell.camera_photometry.residual_edge_px if cell.camera_photometry is not None else 0.0
    source, sigma = ("camera", measured) if measured > 0 else ("optics", cfg.optics_edge_sigma_px)
    if not sigma > 0:
        return []
    return [LineDoubt(source, k, sigma, group="camera_model") for k in EDGE_NAMES]


def _edge_model_doubts(
    plane, r: Refined, cfg: LocateConfig, cell: Cell, strips: dict[str, tuple[int, int]] | None = None
) -> list[LineDoubt]:
    """The doubts the edge models know of each line (:class:`doorloc.vision.uncertainty.LineDoubt`): the
    far-face model's own, else the texture beside the edge (across it and along it; on a plain edge at
    least what :func:`doorloc.vision.edge_texture.plain_edge_texture` measures on it).

    ``strips``: per arris line, the pixels its strip (and the blur beside it) takes on the door side, and
    that side (+1: increasing ``along``); the texture there is read beyond the strip.
    """
    samples, fit, half, far_fit, step_fitted = r.samples, r.fit, r.half, r.far_fit, r.step_fitted
    doubts = []
    lut = linearizing_lut(plane.dtype, cell.response_gamma)
    for k in EDGE_NAMES:
        if k == "far" and far_fit is not None:  # what the far-face model leaves in doubt (band level, blur)
            doubts.append(LineDoubt("far_face", k, far_fit.model_sigma_px))
            continue
        skip, side = (strips or {}).get(k, (0, 1))
        tb = texture_bias(
            plane,
            samples[k],
            fit.weights[k] > 0,
            half,
            cfg.plateau,
            lut,
            blur_px=step_fitted.get(k),
            door_skip_px=skip,
            door_side=side,
            face_slope_half_px=r.face_sloped.get(k),
        )
        # The far arris's offset gives only the thickness: its texture doubt is the thickness's, not the
        # corner's. (Without it the grain set's thicknesses, the hinge face's grain beside the far arris
        # as beside the reference one, were 85 % within 2 sigma.) Its direction votes on the door's in
        # the joint fit where no far face is beside it, so its texture tilt counts in the yaw
        # (:func:`doorloc.vision.uncertainty.propagate`).
        offset, tilt = plain_edge_texture(plane, r, k, tb, lut)
        doubts.append(LineDoubt("texture", k, offset, tilt=tilt))
    return doubts


def _jpeg_doubts(
    samples: dict[str, EdgeSamples], fit: RectangleFit, scale_mm_per_px: float, grey_dn: float
) -> list[LineDoubt]:
    """Each line's JPEG doubt: across it, the quantisation's ``grey_dn`` grey levels over the line's median
    step (:func:`doorloc.vision.uncertainty.jpeg_edge_doubt_px`; the step
    as the area estimator read it, in the plane's grey levels, which a linearised camera's response makes
    a little unlike the encoder's), and the tilt (:func:`doorloc.vision.uncertainty.jpeg_tilt_sigma`) as
    the edge's phase in the blocks and pixels changes along it, and as its error drifts along an edge at
    nearly one phase (:func:`doorloc.vision.uncertainty.jpeg_drift_tilt`)."""
    doubts = []
    for k in EDGE_NAMES:
        inl = (fit.weights[k] > 0) & np.isfinite(samples[k].along)
        scan, along = samples[k].scan[inl], samples[k].along[inl]
        slope = fit_image_line(scan, along).b if scan.size >= 3 else math.nan
        doubt = jpeg_edge_doubt_px(_median_step(samples[k], inl), grey_dn)
        tilt = math.hypot(jpeg_tilt_sigma(slope, scan, doubt), jpeg_drift_tilt(slope, scan, doubt))
        blocks = _block_correlated_tilt(scan, fit.residuals[k][inl] / scale_mm_per_px)
        doubts.append(LineDoubt("jpeg", k, doubt, tilt=math.hypot(tilt, blocks)))
    return doubts


def _quantisation_doubts(
    samples: dict[str, EdgeSamples], fit: RectangleFit, half_px: int, s8: float, noise_dn: float
) -> list[LineDoubt]:
    """Each line's doubt from the image's grey-level rounding where the plateaus' noise (``noise_dn``, 0-255
    scale, as the response check read it: :func:`doorloc.vision.side_patches.plateau_noise_dn`) is too
    small to dither it (:func:`doorloc.vision.quantisation.quantisation_doubt_px`, over the final window of
    ``2 half_px + 1`` pixels, levels of ``s8`` on the 0-255 scale), and the tilt its runs along the line
    give (:func:`doorloc.vision.quantisation.quantisation_tilt`); none where noise dithers it."""
    doubts = []
    for k in EDGE_NAMES:
        inl = (fit.weights[k] > 0) & np.isfinite(samples[k].along)
        doubt = quantisation_doubt_px(_median_step(samples[k], inl), 2 * half_px + 1, noise_dn, s8)
        if doubt > 1e-6:
            doubts.append(
                LineDoubt("quantisation", k, doubt, tilt=quantisation_tilt(doubt, samples[k].scan[inl]))
            )
    return doubts


def _median_step(samples: EdgeSamples, inliers: np.ndarray) -> float:
    """The median grey-level step (0-255, unsigned) of a line's ``inliers``; NaN where none is finite."""
    steps = np.abs(samples.step[inliers])
    steps = steps[np.isfinite(steps)]
    return float(np.median(steps)) if steps.size else math.nan


def _block_correlated_tilt(scan: np.ndarray, residual_px: np.ndarray) -> float:
    """What the line fit's standard error of the tilt (px per px) misses where its residuals are alike
    within each 8-px JPEG block: the slope's standard error from the blocks' mean residuals, less (in
    quadrature) the one from the residuals taken as independent; 0 where that is less or too few blocks.
    (Not :func:`residual_structure_tilt`: its blocks are ``RESIDUAL_BLOCKS`` runs of equal counts along the
    line, for slow texture; JPEG's lie on the image's grid of 8, and a block that straddles two of them
    halves what it shows.)"""
    ok = np.isfinite(residual_px)
    scan, res = scan[ok].astype(np.float64), residual_px[ok].astype(np.float64)
    block = np.floor_divide(scan, 8).astype(np.int64)
    block -= block.min() if block.size else 0
    counts = np.bincount(block)
    used = counts > 0
    if used.sum() < 4 or scan.size < 8:
        return 0.0
    means = np.bincount(block, res)[used] / counts[used]
    centres = np.bincount(block, scan)[used] / counts[used]
    c = centres - centres.mean()
    fitted = means.mean() + c * (means @ c) / (c @ c)
    se_blocks = math.sqrt(float(np.sum((means - fitted) ** 2)) / (means.size - 2) / float(c @ c))
    d = scan - scan.mean()
    se_each = math.sqrt(float(np.sum((res - res.mean()) ** 2)) / (res.size - 2) / float(d @ d))
    return math.sqrt(max(0.0, se_blocks**2 - se_each**2))


def _arris_doubts(
    arris_fits: dict[str, tuple[StripFit, float]],
    samples: dict[str, EdgeSamples],
    fit: RectangleFit,
    scale_mm_per_px: float,
    diagnostics: dict,
) -> list[LineDoubt]:
    """What the arris correction leaves in doubt on each arris line (and its figures into
    ``diagnostics["arris_fit"]``): across it, the strip's fitted deficit times its width, and the blur its
    fit does not share with the other strips (:func:`_arris_blur_doubts`); along it (the strip's shading
    and the texture beside it change along the edge; the texture term reads only beyond the strip), the
    tilt that the residuals' structure over quarters of the line could hide."""
    for k in EDGE_NAMES:
        if k in arris_fits:
            strip, band_px = arris_fits[k]
            diagnostics.setdefault("arris_fit", {})[k] = {
                "deficit": round(strip.deficit, 4),
                "deficit_sigma": round(strip.deficit_sigma, 5),
                "strip_px": round(band_px, 3),
                "blur_px": round(strip.blur_px, 3),
                "misfit": round(strip.misfit, 3),
                "offset_px": round(strip.offset_px, 4),
            }
            if strip.stated_light_misfit is not None:
                # whether the cell's stated light explained this rounding (else fitted as if none were stated)
                diagnostics["arris_fit"][k]["stated_light"] = {
                    "misfit_over_free": round(strip.stated_light_misfit, 3),
                    "used": strip.stated_light_used,
                }
    moved = _arris_blur_doubts(arris_fits, diagnostics)
    doubts = []
    for k in EDGE_NAMES:
        if k not in arris_fits:
            continue
        strip, band_px = arris_fits[k]
        offset = strip.deficit_sigma * band_px
        if k in moved:
            offset = math.hypot(offset, moved[k])
        inl = fit.weights[k] > 0
        tilt = residual_structure_tilt(samples[k], fit.residuals[k] / scale_mm_per_px, inl)
        doubts.append(LineDoubt("arris", k, offset, tilt=tilt))
    return doubts


#: px: the blurs the reference arris's and the far arris's strips read may differ by three of the blur
#: model's plausible errors (``arris_model.BLUR_DOUBT``) before the wider one is doubted by the spread it
#: read as blur (over 129 arris doors of the surfaces bench's combined set and the arris bench, at most
#: 0.24 px apart where both strips were read right)
SIDE_BLUR_APART_PX = 3.0 * BLUR_DOUBT


def _side_blur_spreads(blurs: dict[str, float]) -> dict[str, float]:
    """The side arris whose strip reads a blur wider than the other side arris's by more than
    ``SIDE_BLUR_APART_PX``, and the spread (px, a standard deviation) its fit took for blur that the
    optics do not make: ``sqrt(wider^2 - narrower^2)``, unexplained structure beside or on the strip
    (wood grain along a rounding), over which its border may lie. Seen: a 2.6 mm rounding under 7 %
    grain (``bench_surfaces.py --sets combined --n 40 --seed 9970``, the set's seed 9974, door 37): its
    reference arris's strip read 1.94 px where the far arris's read 1.36 and the bottom end's 1.30 (the
    image's 1.29), and the door was answered 0.54 mm off in x at a sigma of 0.085 mm (6.4 sigma); the
    spread is 1.38 px, 0.28 mm. Refitted at the others' blur the strip kept its valley (its
    ``blur_doubt_px`` 0.02 px)."""
    ref, far = blurs.get("reference"), blurs.get("far")
    if ref is None or far is None:
        return {}
    wider, narrower = ("reference", "far") if ref >= far else ("far", "reference")
    spread = unexplained_spread_px(blurs[wider], blurs[narrower], SIDE_BLUR_APART_PX)
    return {wider: spread} if spread > 0.0 else {}


def _arris_blur_doubts(arris_fits: dict[str, tuple[StripFit, float]], diagnostics: dict) -> dict[str, float]:
    """Each arris line's doubt (px) from a blur its strip fit does not share with the image's other strips.

    One lens blurs every edge of the door alike, but each strip fit finds its own blur, which trades off
    with the strip's shading and the border's place: texture beside a strip (wood grain along a rounding)
    can take a fit to a wrong valley with a wrong blur. Seen on a 3 mm rounding with 6.5 % grain
    (tests/vision/test_arris_model.py): the reference arris's strip read a blur of 1.76 px where the
    bottom end's and the far arris's read 0.72 and 0.85 (the image's 0.72), and the door was placed
    0.51 mm off in x with a sigma of 0.09 mm; that strip fitted at 0.72 px was 0.05 mm off. The strip fit
    allows for ``arris_model.BLUR_DOUBT`` of blur; where a line's blur differs from the strips' median by
    more, the change of its deficit at that median (:attr:`StripFit.deficit_at_blur`, against the same
    search at its own blur) times the strip's width joins its ``arris`` doubt (``arris_correction_sigma_mm``;
    ``diagnostics.arris_fit[line].blur_doubt_px``). The two side arrises lie in the hinge face's plane, in
    one focus, and run the same way (an astigmatic lens blurs them alike): where one's strip reads a blur
    wider than the other's by more than ``SIDE_BLUR_APART_PX``, its border is in doubt by the spread the
    optics do not explain, ``sqrt(wider^2 - narrower^2)`` px (:func:`_side_blur_spreads`).
    """
    blurs = {k: float(strip.blur_px) for k, (strip, _) in arris_fits.items() if math.isfinite(strip.blur_px)}
    out: dict[str, float] = {}
    if len(blurs) < 2:
        return out
    for k, spread in _side_blur_spreads(blurs).items():
        out[k] = spread
        diagnostics.setdefault("arris_fit", {}).setdefault(k, {})["blur_spread_px"] = round(spread, 4)
    # the image's blur: the strips' median (one strip led astray does not move it; of two, their mean)
    shared = float(np.median(list(blurs.values())))
    for k, (strip, band_px) in arris_fits.items():
        if k not in blurs or strip.deficit_at_blur is None:
            continue
        if not abs(blurs[k] - shared) > BLUR_DOUBT:
            continue
        moved = abs(strip.deficit_at_blur(shared) - strip.deficit_at_blur(blurs[k])) * band_px
        if math.isfinite(moved):
            out[k] = math.hypot(out.get(k, 0.0), moved)
            diagnostics.setdefault("arris_fit", {}).setdefault(k, {}).update(
                blur_strips_px=round(shared, 3), blur_doubt_px=round(moved, 4)
            )
    return out


def _response_terms(
    plane, r: Refined, used_gamma: float, response: ResponseFit, blur_px: float, absorbed: bool, factor: float
) -> list[LineDoubt]:
    """Each line's response doubt (px), from the step model.

    The edge was measured with ``used_gamma``; the image reads the camera's exponent as ``response.gamma``
    +- ``response.sigma``. The doubt is built from the shift (:func:`doorloc.vision.response.edge_shift_px`
    between the line's own plateaus, at the measured blur) to the exponent the evidence gives and the
    shift of its 1-sigma, by the rule of :func:`_line_response_doubt`. A weak reading (a line read between
    its pixels, ``response.one_phase``, a door square to the camera) of an exponent no camera gives
    (:func:`doorloc.vision.response.a_cameras_reading`: two lines of a 1.44 camera read 0.40 +- 0.08) is
    no reading: the cell's exponent within ``factor`` alone (:func:`_unmeasured_response_terms`).

    An arris line takes the same step model between its background and its face (a first-order figure).
    """
    if absorbed:
        rule = "absorbed"
    elif response.claimed_sigma > 0:
        rule = "measured"
    elif response.one_phase and factor > 1.0:
        rule = "weak"
        if not a_cameras_reading(response.gamma, response.sigma):
            return _unmeasured_response_terms(plane, r, used_gamma, factor, blur_px)
    else:
        rule = "unmeasured"
    # the exponent the evidence gives, gc +- sc
    if rule == "measured":
        gc, _, sc = response.combined
    elif rule == "weak":
        gc, sc = response.with_unmeasured_claim(used_gamma * (factor - 1.0))
    else:
        gc, sc = response.gamma, response.sigma
    alternatives = list(response.alternatives)
    if rule in ("unmeasured", "weak") and factor > 1.0:
        alternatives = _within_claim(alternatives, used_gamma, factor)
    n_alt = len(alternatives)
    # a kept measured claim's doubt is never less than the image's own reading leaves: its shifts too
    own = []
    if rule == "measured":
        own = [response.gamma, response.gamma + response.sigma, max(response.gamma - response.sigma, 0.05)]
    per_line = {}
    for k, shifts in _line_response_shifts(plane, r, used_gamma, blur_px):
        at = shifts([gc, gc + sc, max(gc - sc, 0.05), *alternatives, *own])
        per_line[k] = _line_response_doubt(rule, at[:3], at[3 : 3 + n_alt], at[3 + n_alt :])
    return _response_doubts(per_line)


def _within_claim(alternatives: list[float], used_gamma: float, factor: float) -> list[float]:
    """The exponents the edges admit about as well as their reading (``alternatives``), brought within the
    cell's claim: ``used_gamma`` known within ``factor`` (``LocateConfig.response_unmeasured_factor``), the
    range the doubt of a response nobody measured spans where the image reads none
    (:func:`_unmeasured_response_terms`). An alternative beyond it counts as the range's end: the camera
    may lie anywhere up to the end, but a camera the cell's own claim rules out is not why an image that
    reads a response should doubt it more than an image that reads none. (A plain grained door of a linear
    camera in a cell of 1.0, read 1.28 +- 0.15 with alternatives up to 2.99, kept x 0.20 mm of response
    doubt on an error of 0.003 mm and was refused.)"""
    lo, hi = used_gamma / factor, used_gamma * factor
    return sorted({min(max(float(a), lo), hi) for a in alternatives})


def _line_response_doubt(rule: str, evidence: np.ndarray, alternatives: np.ndarray, own: np.ndarray) -> float:
    """One line's response doubt (px) from the shifts (px) to the evidence's exponent and to it +- its
    1-sigma (``evidence``, 3), to the other exponents the edges admit about as well (``alternatives``), and
    (``measured`` only) to the image's own reading and to it +- its 1-sigma (``own``, 3), by ``rule``:

    - ``absorbed`` (the exponent in use is this image's reading): the reading's 1-sigma shift, and what
      the shift to it leaves beyond twice that;
    - ``measured`` (the cell's exponent was itself measured, ``response.claimed_sigma``, and is kept; the
      evidence is :attr:`ResponseFit.combined`): the shift to the exponent both measurements give together
      and its 1-sigma shift (widened by their disagreement), in quadrature; and never less than the image's
      reading alone leaves an unmeasured cell (below): a measurement the image disputes buys no confidence
      (a claim of 1.8 +- 0.05 for a 2.2 camera read 2.13 +- 0.11 combines to 1.86 +- 0.12, and the truth
      lies 2.8 of those off);
    - ``unmeasured`` (the edges were read at many pixel phases): the shift to the reading beyond the
      reading's 1-sigma shift, the least the camera is off the cell's exponent at one sigma (within it, the
      edges agree with the exponent in use, and a right cell keeps its small sigma), or the largest shift
      to the alternatives beyond twice that (the image cannot tell which the camera has; each alternative
      brought within the cell's claim, :func:`_within_claim`). Counted beyond
      twice the 1-sigma shift (the rule until 2026-11-30), a plain door under a halo with a cell of 1.0
      for a 1.12 camera, read 1.115 +- 0.052 (2.2 sigmas off), kept almost no response doubt and its
      thickness was 0.045 mm off at 5.8 sigma (``bench/bench_arris_range.py --n 32 --seed 9100 --sets
      sharp_halo --cell-gamma-off bound``, door 21102; 1.9 sigma now), while right cells' sigmas hardly
      move (the same doors with the camera's exponent: thickness median sigma 0.0036 -> 0.0037 mm);
    - ``weak`` (a line read between its pixels, against a cell exponent nobody measured): such a reading
      (+-0.2-0.6) is weak evidence, and agreeing within two of its sigmas proves little (a cell of 1.0 for a
      1.67 camera, read 1.65 +- 0.34, was answered 0.056 mm off at 4.4 sigma). The evidence is the cell's
      exponent, taken as known within ``LocateConfig.response_unmeasured_factor``, and the reading together
      (:meth:`ResponseFit.with_unmeasured_claim`): the shift to their exponent and its 1-sigma shift in
      quadrature, or the largest shift to an alternative (within the claim, as above).

    That combination was tried on every reading and not taken: readings at many phases under strong
    shading, vignetting and noise read a linear camera 0.4-0.9 +- 0.2, and the combination put
    0.007-0.026 mm on each line of right cells' doors (tests/vision's hard photometry; the parity set's
    ``rand`` renders, sigma up to 0.012 -> 0.079 mm); and weighing a point "the cell is exactly right"
    against "another within the factor" by the reading's likelihood left square doors under a wrong cell
    85 % within 2 sigma (bench_arris square-wrong-gamma --seed 9000), a weak reading favouring the point.
    """
    bias, sp = float(evidence[0]), 0.5 * abs(float(evidence[1]) - float(evidence[2]))
    if rule == "absorbed":
        return math.hypot(max(abs(bias) - 2.0 * sp, 0.0), sp)
    if rule == "measured":
        own_bias, own_sp = float(own[0]), 0.5 * abs(float(own[1]) - float(own[2]))
        return max(math.hypot(bias, sp), abs(own_bias) - own_sp)
    if rule == "weak":
        return max([math.hypot(bias, sp), *(abs(float(v)) for v in alternatives)])
    return max([abs(bias) - sp, 0.0, *(abs(float(v)) - 2.0 * sp for v in alternatives)])


def _response_doubts(px: dict[str, float]) -> list[LineDoubt]:
    """The camera response's doubts of the lines (px; the finite ones): one correlation group, as one camera
    exponent moves every edge."""
    return [LineDoubt("response", k, v, group=CAMERA_RESPONSE) for k, v in px.items() if math.isfinite(v)]


def _unmeasured_response_terms(
    plane,
    r: Refined,
    used_gamma: float,
    factor: float,
    blur_px: float,
    allowed: AllowedEnds | None = None,
    figures: dict[str, Any] | None = None,
) -> list[LineDoubt]:
    """The response doubt (px) of each line when the image did not measure the camera's response.

    The response is measured on plain edges only (:func:`measure_response`): the shading of an arris
    strip is free in its fit and takes up what a wrong exponent does to the profile (a fit of the exponent
    to the strip's misfit was tried: on the arris bench it found the camera's exponent on some chamfers
    and 0.8 or 3.0 on others, right cell or not); a plain edge along a pixel row or column blurred by
    less than ``RESPONSE_ONE_PHASE_MIN_BLUR_PX`` cannot be read between its pixels, and sharp edges are not
    read (:func:`response_check_applies`). Then the cell's
    ``response_gamma`` cannot be checked, and it is taken as known within a factor ``factor``
    (``LocateConfig.response_unmeasured_factor``): the doubt of every line (the far one's where no far-face
    model reports its own) is half the spread of the edge shift
    (:func:`doorloc.vision.response.edge_shift_px`, the line's plateaus, the measured blur) between
    ``used_gamma * factor`` and ``used_gamma / factor``. Without it the arris lines' answers under a wrong
    cell exponent were biased by several of their sigmas (fixtures/rendered/effects: 1.0 for a 2.2
    camera, z 0.035 mm at 2-3 sigma), and a plain door square to the camera by up to 7 (a 1.13 camera in
    a cell of 2.01, blur 0.86 px: x 0.075 mm off at sigma 0.010).

    An arris line's shifts are its own model's where ``allowed`` is given (the door's strips read again
    with the exponents at the ends, per line the shifts out, px: :func:`doorloc.vision.strip_response.
    allowed_response_ends` over :func:`doorloc.vision.refine.arris_response_shifts`): its fitted shading
    takes up part of the distortion that moves a plain step, or adds to it (on three 0.65-0.87 mm
    roundings located again with the cell at the two exponents, the plain step's figure was 0.5-3.7
    times the door's real move; the strip's own, 0.9-2.3 times). Its
    doubt is half the range of the shifts at the two exponents and at ``used_gamma`` (no shift), which
    is the plain step's half spread where the two move it apart, and half the larger where both move it
    the same way. A line whose strip is lost at an exponent keeps the plain step's figure. Where the
    door's strips rule out the factor's far exponents (read with them, a rounding's shading is no matt
    arc's, or a chamfer's fitted profiles miss the image's grey levels), the two ends are the exponents
    they allow, for every line; ``figures["response_from_strips"]`` says what they showed.

    The doubt is the move at the factor's ends, not its RMS over the exponents within them
    (``sqrt((s_up^2 + s_down^2) / 6)`` for a move linear in the log exponent, 0.6 of this figure where
    the ends move the line apart), because the case it is for is a cell off by the whole factor (a
    linear camera assumed for an sRGB one), and there the answers already sit near two of their sigmas:
    fixtures/rendered/effects (a cell of 1.0 for a 2.2 camera) worst 1.79 sigma in x and 1.87 in the
    thickness; bench/bench_arris_range.py ``--cell-gamma-off bound --seed 7300`` (round, chamfer,
    ambient, small) worst 1.69, 90 % within 1.4. With the RMS those fixtures were 74 % (x), 81 % (z) and
    22 % (thickness) within 2 sigma, and the bench's ambient set 80 % (z) and 73 % (thickness). With the
    cell's exponent right, the same doubts are many times the errors (``--seed 7300``: 90 % of the
    errors within 0.13 of their sigma, and arris doors refused as uncertain): that is the price of a
    response nobody measured, and measuring it (``doorloc calibrate``, a factor near 1.1) is the remedy.
    """
    if not factor > 1.0:
        return []
    ends: list[float] = [used_gamma * factor, used_gamma / factor]
    own: dict[str, tuple[float, float]] = {}
    if allowed is not None:
        ends, own = list(allowed.gammas), allowed.shifts
        if figures is not None:
            # (each arris line's shifts, px, at the two ends: diagnostics.arris_fit[line])
            for k, v in own.items():
                figures.setdefault("arris_fit", {}).setdefault(k, {}).update(
                    response_gammas=[round(float(g), 3) for g in ends],
                    response_shifts_px=[round(float(x), 4) if math.isfinite(x) else None for x in v],
                )
            if allowed.figure:
                figures["response_from_strips"] = allowed.figure
    per_line = {}
    for k, shifts in _line_response_shifts(plane, r, used_gamma, blur_px):
        if k in own and np.all(np.isfinite(own[k])):
            moved = [0.0, *own[k]]
            per_line[k] = 0.5 * (max(moved) - min(moved))
            continue
        up, down = shifts(ends)
        spread = 0.5 * abs(float(up) - float(down))
        per_line[k] = spread
    return _response_doubts(per_line)


def _line_response_shifts(
    plane, r: Refined, used_gamma: float, blur_px: float
) -> Iterator[tuple[str, Callable[[list[float]], np.ndarray]]]:
    """Each line a camera exponent moves (the far one only where no far-face model reports its own doubt)
    and the shifts, px, that exponents make there (a list in, an array out: the step is modelled once for
    all of them): :func:`doorloc.vision.response.edge_shifts_px` between the line's own plateaus at
    ``blur_px``, each exponent brought within ``RESPONSE_PLAUSIBLE`` (a reading or a factor beyond them is
    no camera)."""
    samples, fit, half, far_beside = r.samples, r.fit, r.half, r.far_beside
    for k in EDGE_NAMES:
        if k == "far" and far_beside:
            continue
        inl = fit.weights[k] > 0
        lo, hi = plateau_levels(plane, samples[k], inl & samples[k].valid, half)

        def shifts(gs: list[float], lo: float = lo, hi: float = hi) -> np.ndarray:
            g = np.clip(np.asarray(gs, float), *RESPONSE_PLAUSIBLE)
            return edge_shifts_px(lo, hi, g, used_gamma, blur_px, half)

        yield k, shifts
