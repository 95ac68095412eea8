"""The response check stage of locate: the camera's response read off the plain edges of the image, and
where it differs from the cell's, a wider window confirms it and no line's transition overshoots both its
plateaus (a camera that sharpens, :mod:`doorloc.vision.response_overshoot`), the edges refined again with
the image's own exponent (absorbed) and read once more (:func:`check_response`). What it finds is a
:class:`doorloc.vision.state.ResponseCheck`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from doorloc.cell import Cell
from doorloc.vision.arris_model import StripFit
from doorloc.vision.blurred_step import STEP_FIT_MIN_BLUR_PX
from doorloc.vision.config import LocateConfig
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.lines import RectangleFit
from doorloc.vision.metric import MetricPose
from doorloc.vision.region import EDGE_NAMES
from doorloc.vision.response import (
    RESPONSE_ONE_PHASE_MIN_BLUR_PX,
    LineResponse,
    ResponseFit,
    a_cameras_reading,
    at_one_phase,
    combine_responses,
    edge_shifts_px,
    fit_line_response,
)
from doorloc.vision.response_overshoot import line_overshoot
from doorloc.vision.sampling import linearizing_lut
from doorloc.vision.side_patches import plateau_noise_dn, side_patches
from doorloc.vision.state import Refined, ResponseCheck
from doorloc.vision.texture import texture_bias
from doorloc.vision.transition import blur_without_pixel

__all__ = [
    "PLAIN_STRIP_PX",
    "RESPONSE_OVERSHOOT_MAX",
    "RESPONSE_MIN_NOISE_DN",
    "check_response",
    "measure_response",
    "response_check_applies",
]


#: an arris strip narrower than this, px, is a plain step to the camera response's check (a chamfer of a few
#: thousandths of a millimetre, a twentieth of a pixel: its lines are plain edges, on which the response is
#: measured; as arris lines the unmeasured response's doubt put 0.19 mm on an answer 0.001 mm off)
PLAIN_STRIP_PX = 0.1

#: px added to each side of a plain edge's window to read its exponent again before the image's reading
#: replaces the cell's (:func:`_read_otherwise_wider`)
RESPONSE_WIDER_CHECK_PX = 3

#: the overshoot of a plain edge's mean transition beyond both its plateaus (a fraction of the step,
#: :func:`doorloc.vision.response_overshoot.line_overshoot`) from which its reading does not replace the
#: cell's exponent: a camera that sharpens (a 1.85 camera sharpened by 0.36 at 2 px, whose sensor noise hid
#: it from the gate's sharpening check: 0.030-0.031 on its two lines, read 1.12 +- 0.02, absorbed and
#: answered 0.066 mm off at 2.9 sigma; the cell's exponent kept, 0.021 mm off). Unsharpened, the benches'
#: plain edges read at most 0.011 (JPEG doors, quality 80-95), 0.017 (grain and JPEG, bench_surfaces.py),
#: below 0 through a halo
RESPONSE_OVERSHOOT_MAX = 0.02

#: plateau noise (1-sigma, 0-255 scale, as :func:`doorloc.vision.side_patches.plateau_noise_dn` reads it)
#: under which the plain edges' response is not read: the grey levels' rounding, undithered, bends the
#: transitions (a linear camera's door rendered without noise, step 37, read 2.19 +- 0.03 and replaced the
#: cell's 1.0: x 0.11 mm off at 17 sigma; with 0.1 grey of read noise its reference arris still read 2.26 +-
#: 0.03, with 0.2 it read 1.01. Read noise of 0.1 reads 0-0.18 on four doors, of 0.2 0.23-0.31, but 0 on
#: a door whose plateaus all sit near whole levels, up to 0.25)
RESPONSE_MIN_NOISE_DN = 0.15


def check_response(
    plane: np.ndarray,
    cell: Cell,
    cfg: LocateConfig,
    refined: Refined,
    refine_again: Callable[[MetricPose, float], Refined],
    s8: float = 1.0,
) -> ResponseCheck:
    """The response check stage: the camera response read off the plain edges, and where it differs from
    the cell's (and a window ``RESPONSE_WIDER_CHECK_PX`` wider on each side confirms it:
    :func:`_read_otherwise_wider`), the edges refined again with it (the absorb-and-rerun,
    ``refine_again(pose, gamma)``: the refine stage from ``pose`` with the camera exponent ``gamma``) and
    read once more. Under ``locate.response_check: where_unmeasured`` a cell whose response was measured
    is not read again (the doubts stage then takes its exponent within
    ``locate.response_unmeasured_factor``). A plain edge whose plateaus are quieter than
    ``RESPONSE_MIN_NOISE_DN`` (``s8``: the plane's scale to 0-255) is not read either."""
    used_cell = cell
    trusted = cfg.response_check == "where_unmeasured" and cell.response_gamma_sigma is not None
    noise = plateau_noise_dn(side_patches(plane, refined.samples, refined.fit.weights), s8)
    quiet = noise < RESPONSE_MIN_NOISE_DN
    response, per_line = (None, {}) if trusted else measure_response(plane, refined, cell, cfg, quiet=quiet)
    response_diag: dict[str, Any] = {"cell_gamma": cell.response_gamma, "absorbed": False}
    unstable: float | None = None
    if cell.response_gamma_sigma is not None:
        response_diag["cell_sigma"] = cell.response_gamma_sigma
    if (
        response is not None
        and response.absorb
        and _a_camera_reading(plane, refined, cell, cfg, per_line, response_diag)
    ):
        # The plain edges show another camera response than the cell's: measure again with theirs (the
        # bias a wrong response gives every edge, arris strips included, is then gone), and check again.
        response_diag.update(absorbed=True, first_fit=round(response.gamma, 4))
        first = refined
        used_cell = replace(cell, response_gamma=response.gamma, response_gamma_sigma=None)
        refined = refine_again(refined.pose, response.gamma)
        again = measure_response(plane, refined, used_cell, cfg, quiet=quiet)
        if again[0] is not None and again[0].departs:
            # Read again with the absorbed exponent in use, the edges show yet another one: their reading
            # depends on where the edges were placed, so it is no measurement of the camera (seen: a lens
            # distortion the cell models only in part, k1 0.17 for 0.20; 2.68 read with the cell's 1.0,
            # then 1.02 read with 2.68, and the answer refused for a 0.1 mm response doubt). The cell's
            # exponent stands, unchecked. Yet another, whether or not a camera has it: a grained door of a
            # 2.2 camera stated so read 0.84 and absorbed it, then read 0.42 +- 0.09 (its bottom end at the
            # range's end, 0.4), no camera's exponent and so nothing to absorb, and the answer rested on
            # 0.84: x 0.041 mm off at 3.2 sigma.
            unstable = round(again[0].gamma, 4)
            refined = first
            used_cell, response = cell, None
            response_diag.update(absorbed=False, second_fit=unstable)
        elif again[0] is not None:
            response, per_line = again
    response_diag["checked"] = response is not None
    # whose exponent the answer rests on: the cell's (measured or stated) or this image's own
    response_diag["used"] = "image" if response_diag["absorbed"] else "cell"
    if response is None:
        response_diag["unchecked_because"] = _unchecked_because(
            trusted, unstable, refined, quiet, response_diag
        )
    if response is not None:
        response_diag.update(
            fitted=round(response.gamma, 4),
            sigma=round(response.sigma, 4),
            lines={
                k: {"gamma": round(v.gamma, 4), "sigma": round(v.sigma, 4), "skew_px": round(v.skew_px, 4)}
                | ({"one_phase": True} if v.one_phase else {})
                | ({"alternatives": [round(a, 4) for a in v.alternatives]} if v.alternatives else {})
                for k, v in per_line.items()
            },
        )
        if response.alternatives:
            response_diag["alternatives"] = list(response.alternatives)
    return ResponseCheck(refined, used_cell, response, bool(response_diag["absorbed"]), response_diag, noise)


def response_check_applies(samples: EdgeSamples, inliers: np.ndarray, blur_px: float) -> bool:
    """Whether the mean transition's asymmetry can be read on this line.

    The check averages the profiles on a fine grid aligned on the sub-pixel edge: that mean shows the
    response's asymmetry where the line's edge points fall at many pixel phases and the edge is blurred
    over more than half a pixel. (A sharp step integrated over the pixel is a one-pixel ramp, straight
    in linear light and bent by a wrong exponent, and reads too: a 1.6 camera in a cell of 1.0 read 1.61
    +- 0.10, a linear one in a cell of 2.2 1.01 +- 0.12; but at ~9 ms a line it made the sharp grid set's
    frames 2.3 times slower. Such a line takes the cell's exponent within
    ``LocateConfig.response_unmeasured_factor`` instead, :mod:`doorloc.vision.doubts`: 0.028 mm on
    the sharp grid fixtures.) An edge along a pixel row or column puts all of them at one phase; its
    transition is read between the pixels by interpolation, which needs a blur of
    ``RESPONSE_ONE_PHASE_MIN_BLUR_PX`` (unread and without a doubt, doors square to the camera in a cell
    whose exponent was not the camera's had been answered 5-7 sigma off).
    """
    if not blur_px >= STEP_FIT_MIN_BLUR_PX:  # (the phases need not be counted then)
        return False
    return _at_many_phases(samples, inliers) or blur_px >= RESPONSE_ONE_PHASE_MIN_BLUR_PX


def _at_many_phases(samples: EdgeSamples, inliers: np.ndarray) -> bool:
    """Whether the line's edge points fall in every quarter of a pixel (not along a pixel row or column)."""
    m = inliers & samples.valid
    return bool(m.any()) and not at_one_phase(samples.scan[m], samples.along[m])


def _a_camera_reading(
    plane, refined: Refined, cell: Cell, cfg: LocateConfig, per_line: dict[str, LineResponse], diag: dict
) -> bool:
    """Whether the plain edges' reading, which differs from the cell's exponent, is a measurement of the
    camera to replace it with: not where a line's transition overshoots both plateaus (no blurred step's:
    a camera that sharpens, :func:`_overshooting`, ``diag["overshoot"]``), nor where a line reads another
    exponent over a wider window (texture or shading beside it, :func:`_read_otherwise_wider`,
    ``diag["wider_window_fit"]``). Otherwise the cell's exponent stands, and the reading still sizes its
    doubt (a camera changed since its calibration, under texture, is then covered rather than answered with
    the calibration's small doubt)."""
    overshooting = _overshooting(plane, refined, per_line)
    if overshooting:
        diag["overshoot"] = overshooting
        return False
    wider = _read_otherwise_wider(plane, refined, cell, cfg, per_line)
    if wider:
        diag["wider_window_fit"] = wider
    return not wider


def _read_otherwise_wider(
    plane, refined: Refined, cell: Cell, cfg: LocateConfig, per_line: dict[str, LineResponse]
) -> dict[str, float | None]:
    """The lines whose exponent, read again over a window ``RESPONSE_WIDER_CHECK_PX`` wider on each side,
    lies beyond twice the two readings' sigmas from the first and does not depart from the cell's exponent
    the same way by half to twice as much, or is an exponent no camera has
    (:func:`doorloc.vision.response.a_cameras_reading`), or is not read; with that reading (None where
    none). A clean step's transition reads the same whatever plateaus are added beside it; a transition
    that texture or shading skews (a grain stripe's flank, a face brighter near its edge) reads another
    exponent as the window takes in more of it. On a linear camera under grain, vignetting and JPEG (grain
    bench, seed 9900, door 30) both plain edges read 2.4-2.7 +- 0.1-0.4 and the cell's right 1.0 was
    replaced: the thickness 0.083 mm off at 5.3 sigma; over a window 3 px wider the reference arris read
    0.45. A 2.2 camera stated so under 10 % grain and JPEG 88 (the grain set's door 38 at ``--seed 55100``
    through that camera, its figures rounded to five digits) read 0.84 +- 0.15 and 0.79 +- 0.55, over the
    wider window 0.56 +- 0.07 and 0.44 +- 0.08, within the first readings' sigmas but no camera's
    exponent: 0.84 replaced the cell's, and the door was placed 0.041 mm off at 3.2 sigma."""
    if not per_line:
        return {}
    _, wider = measure_response(plane, refined, cell, cfg, wider_px=RESPONSE_WIDER_CHECK_PX)
    out: dict[str, float | None] = {}
    c = cell.response_gamma
    for k, v in per_line.items():
        w = wider.get(k)
        if w is None:
            out[k] = None
            continue
        agree = abs(w.gamma - v.gamma) <= 2.0 * math.hypot(v.sigma, w.sigma)
        # (a response beyond a power law, a shoulder, reads a somewhat other exponent as the window grows,
        # but departs from the cell's the same way: 1.42 and 1.30 for a cell of 1.0)
        confirms = v.gamma != c and 0.5 <= (w.gamma - c) / (v.gamma - c) <= 2.0
        # (and whichever: a reading that the wider window takes to an exponent no camera has is the
        # texture's or the shading's, however near the first it lies)
        if not (a_cameras_reading(w.gamma, w.sigma) and (agree or confirms)):
            out[k] = round(w.gamma, 4)
    return out


def _overshooting(plane, refined: Refined, per_line: dict[str, LineResponse]) -> dict[str, float]:
    """The lines whose mean transition, linearised with their reading, overshoots both plateaus by
    ``RESPONSE_OVERSHOOT_MAX`` of its step or more, with that figure
    (:func:`doorloc.vision.response_overshoot.line_overshoot`)."""
    blur_px = blur_without_pixel(refined.blur_px)
    out = {}
    for k, v in per_line.items():
        inl = refined.fit.weights[k] > 0
        o = line_overshoot(plane, refined.samples[k], inl, refined.half, v.gamma, blur_px)
        if math.isfinite(o) and o >= RESPONSE_OVERSHOOT_MAX:
            out[k] = round(o, 4)
    return out


def _plain_response_lines(arris_fits: dict[str, tuple[StripFit, float]] | None) -> list[str]:
    """The lines the camera response is read on: the bottom end and the reference arris unless an arris strip
    lies along them (not the far arris: a far face seen edge-on can make a narrow band beside it)."""
    return [
        k
        for k in EDGE_NAMES
        if k != "far" and not (arris_fits and k in arris_fits and arris_fits[k][1] > PLAIN_STRIP_PX)
    ]


def _unchecked_because(
    trusted: bool, unstable: float | None, refined: Refined, quiet: bool, diag: dict[str, Any]
) -> str:
    """Why the response was not checked: the cell's measured response ``trusted``, a reading ``unstable``
    under the exponent it would have replaced (``diag["first_fit"]``), or what the edges could not show
    (:func:`_response_unchecked_because`)."""
    if trusted:
        return (
            "the cell's response was measured (camera.response_gamma_sigma) and locate.response_check is "
            "where_unmeasured: the image is not read again"
        )
    if unstable is not None:
        return (
            f"the edges read {diag['first_fit']} with the cell's exponent in use and {unstable} "
            "with that one: a reading that follows the edges' placement, not the camera's response"
        )
    return _response_unchecked_because(
        refined.samples, refined.fit, refined.blur_px, refined.arris_fits, quiet
    )


def _response_unchecked_because(
    samples: dict[str, EdgeSamples],
    fit: RectangleFit,
    transition_px: float,
    arris_fits: dict[str, tuple[StripFit, float]] | None,
    quiet: bool = False,
) -> str:
    """Why no edge of this image could show the camera response (``diagnostics.camera_response``): the
    pose then rests on the cell's ``response_gamma`` within ``locate.response_unmeasured_factor``, which a
    user should know. ``quiet``: the image's plateaus were too quiet to read the response."""
    plain = _plain_response_lines(arris_fits)
    if not plain:
        return "every edge is an arris strip, whose shading takes up the response"
    if not blur_without_pixel(transition_px) >= STEP_FIT_MIN_BLUR_PX:
        return "the edges are sharper than half a pixel: their transition is not read"
    if not any(_at_many_phases(samples[k], fit.weights[k] > 0) for k in plain):
        return (
            "the plain edges lie along pixel rows or columns (a door square to the camera): one pixel phase, "
            f"where only a transition blurred by {RESPONSE_ONE_PHASE_MIN_BLUR_PX:g} px or more can be read "
            "between the pixels"
        )
    if quiet:
        return (
            f"the plain edges' plateaus are quieter than {RESPONSE_MIN_NOISE_DN:g} grey levels (a render without "
            "noise, or a camera that denoises): the rounding of their grey levels, undithered, bends the "
            "transitions' shape"
        )
    return "the plain edges' transitions were too noisy or too few to read"


def measure_response(
    plane,
    refined: Refined,
    cell: Cell,
    cfg: LocateConfig,
    wider_px: int = 0,
    quiet: bool = False,
) -> tuple[ResponseFit | None, dict[str, LineResponse]]:
    """The camera response measured on the plain edges (:func:`doorloc.vision.response.fit_line_response`).

    Plain: the bottom end and the reference arris without an arris strip, at many pixel phases and blurred
    (:func:`response_check_applies`); none where ``quiet`` (plateaus too quiet to dither their rounding).
    None where no edge qualifies. ``wider_px``: pixels added to each line's window on each side.
    """
    samples, fit, half, arris_fits = refined.samples, refined.fit, refined.half, refined.arris_fits
    blur_px = blur_without_pixel(refined.blur_px)
    per_line: dict[str, LineResponse] = {}
    for k in _plain_response_lines(arris_fits):
        inl = fit.weights[k] > 0
        if quiet or not response_check_applies(samples[k], inl, blur_px):
            continue
        lr = fit_line_response(plane, samples[k], inl, half, cell.response_gamma, blur_px, wider_px)
        if lr is None:
            continue
        # Texture beside the edge (grain along it) skews the transition the same way on every scan line,
        # which the block scatter does not see: the edge bias it can make (the texture term) read as an
        # exponent error through the step model's sensitivity, in quadrature.
        tex = texture_bias(
            plane, samples[k], inl, half, cfg.plateau, linearizing_lut(plane.dtype, cell.response_gamma)
        ).offset_sigma_px
        dg = 0.05 * lr.gamma
        up, down = edge_shifts_px(
            lr.lo, lr.hi, np.array([lr.gamma + dg, lr.gamma - dg]), lr.gamma, blur_px, half
        )
        slope = abs(float(up) - float(down)) / (2 * dg)
        if math.isfinite(tex) and tex > 0 and slope > 0:
            lr = replace(lr, sigma=math.hypot(lr.sigma, tex / slope))
        per_line[k] = lr
    return combine_responses(per_line, cell.response_gamma, cell.response_gamma_sigma or 0.0), per_line
