"""The doubt of a shoulder in a camera response that nobody measured beyond a power law.

A cell describes its camera's response by one exponent (``camera.response_gamma``) unless its calibration
carries the camera's photometric model (``Cell.camera_photometry``, from ``doorloc calibrate --optics`` or
``doorloc check-model --boards``).
Real cameras' responses bend below full scale: both public cameras' board photographs read a shoulder (OpenCV's
left camera from 0.69 of full scale, Bouguet's from 0.48 above its pedestal), which compresses every level
above it. An edge whose bright side or arris strip lies there is skewed as a wrong exponent skews it, but
no power law near the cell's describes it, so neither the plain edges' response reading nor an unmeasured
response's doubt at the factor's ends (:mod:`doorloc.vision.doubts`) sees it. Measured before this doubt
was built (``bench/bench_camera_doors.py --model <OpenCV's report> --seed 81000`` and ``--seed 79000``,
the cell stating the camera's nearest power law, 0.999): chamfered doors whose bright level lay at 0.85-0.95
of full scale were answered 0.05-0.18 mm off in x and z, up to 2.6 sigma (door_012: a 1.11 mm chamfer,
0.181 mm off in x at a sigma of 0.069).

Where the image could not check the response of an arris door (every edge an arris, or none readable), or
a door's plain edges read an exponent that replaced the cell's (a shoulder skews plain transitions as a
steeper exponent does: that exponent may be its stand-in), and nobody measured the response where the image
reaches (:func:`doubted_knee`: the cell has no photometric model, or its model's board photographs read the
response only up to a lower level and found no shoulder below it), the door is located again as if its
camera had a shoulder from ``knee`` (``locate.response_shoulder_knee``, or that level where higher) up to
full scale (:func:`shouldered_camera`: the image's levels above the knee mapped back to the response they
compress), with the cell's limits lifted; the answer's move is one more
term of its uncertainty (``uncertainty_budget``'s ``response_shoulder``), in full: on the doors above, the move
to a shoulder from 0.7 was 0.55-0.8 of the answers' errors and of their sign's opposite, so half of it (as two
readings weighed alike) would have left them beyond 2 sigma. A door whose image holds no level above the knee
is not located again (the mapping is the identity there).

The door's arris strips can rule the shoulder out, as they rule out exponents: read through it, a chamfer's
borders no longer reproduce the image's grey levels, and a lit rounding's shading no matt arc's, where the
camera keeps its power law (:func:`shoulder_ruled_out`); so can its plain edges, which read through it still
read another exponent than the cell's and replace it (:func:`plain_edges_rule_out`); the answer then stands as
it was. Without that evidence (strips that fit either way alike: a rounding under ambient light, or lit from
where its arcs cannot tell) the move counts: the price of a response nobody measured beyond a power law, which
``doorloc calibrate --optics`` or ``doorloc check-model --boards`` measures once on board photographs (its
photometric model in the calibration lifts the doubt up to the level those photographs reach).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from doorloc.photometric.model import PhotometricModel
from doorloc.vision.arris_model import StripFit
from doorloc.vision.config import LocateConfig
from doorloc.vision.gate import uncertain_pose_words, within_pose_limits
from doorloc.vision.luminance import LuminancePlane
from doorloc.vision.result import LocateResult
from doorloc.vision.strip_response import (
    ARC_EXPLAINS,
    ARC_RULED_OUT,
    GREY_EXPLAINS,
    GREY_RULED_OUT,
    arc_score,
    grey_score,
)
from doorloc.vision.uncertainty import BudgetTerm

__all__ = [
    "plain_edges_rule_out",
    "doubted_knee",
    "shoulder_doubted",
    "shoulder_ruled_out",
    "shouldered_camera",
    "strip_misfit",
    "widened_by_shoulder",
]


def doubted_knee(knee: float, measured: PhotometricModel | None) -> float:
    """The level (fraction of full scale) from which a shoulder in the camera's response is doubted; 1: none.

    ``knee`` (``locate.response_shoulder_knee``) for a camera whose cell states no more than its exponent
    (``measured`` None: no photometric model); for one whose model was measured on board photographs, none
    where the model bends the response's top itself (a shoulder, a white level or a clip below full scale:
    the top was measured), else from the level its photographs read the response up to
    (``response_measured_to``) or ``knee``, whichever is higher: a power law measured to 0.6 of full scale
    says nothing of a shoulder at 0.8."""
    if measured is None or knee >= 1.0:
        return knee
    if measured.shoulder < 1.0 or measured.white_level < 1.0 or measured.clips:
        return 1.0
    return max(knee, measured.response_measured_to)


def shouldered_camera(
    gamma: float, knee: float, measured: PhotometricModel | None = None
) -> PhotometricModel:
    """The camera of the cell's power law ``gamma`` (or of its measured photometric model ``measured``) with a
    shoulder from ``knee`` (fraction of full scale) reaching full scale
    (:class:`doorloc.photometric.model.PhotometricModel`'s finite shoulder)."""
    if measured is not None:
        return measured.with_values(shoulder=float(knee))
    return PhotometricModel(gamma=float(gamma), shoulder=float(knee))


def shoulder_doubted(answer: LocateResult, lum: LuminancePlane, knee: float, arris_mm: float) -> bool:
    """Whether ``answer`` takes the doubt of a shoulder from ``knee`` (:func:`doubted_knee`; 1: none):
    answered, some level of the image (``lum``, before any mapping) above the knee, and either

    - the door with arrises (``arris_mm`` > 0) and the response not checked on the image, or
    - the image's plain edges read another exponent than the cell's and it replaced the cell's
      (``diagnostics.camera_response.absorbed``): a shoulder skews the plain transitions as a steeper exponent
      does, so the exponent read may be a shoulder's stand-in, which places every edge wrongly (measured
      on OpenCV's left camera's model, ``bench/bench_camera_doors.py --model <its report> --seed 75000``,
      door_007: a plain door whose image reached 0.90 of full scale read 2.77 +- 0.27 for the cell's
      0.999 and was answered 0.13 mm off at 4.4 sigma; located through a shoulder from 0.7 at the cell's
      exponent, its edges read 0.99, the cell's own, and it was 0.009 mm off; unless its plain edges rule
      the shoulder out, :func:`plain_edges_rule_out`).

    Not a plain door whose edges read the cell's exponent (or could not be read): its steps' levels are free
    in their fits and a shoulder skews them as a wrong exponent does, which the reading or the unmeasured
    response's doubt already sizes. Measured on the parity harness's golden plain doors (95 of them reaching
    the knee, none absorbed): the shoulder moved them by at most 0.0055 mm, 0.09 of their sigma, for twice the
    locate's time; its 27 arris doors up to 0.012 mm (0.33 sigma)."""
    if not answer.ok or not knee < 1.0:
        return False
    unread_arris = arris_mm > 0.0 and not answer.diagnostics.get("camera_response", {}).get("checked", False)
    if not unread_arris and _exponent_read(answer) is None:
        return False
    top = 255.0 if lum.plane.dtype == np.uint8 else 65535.0
    return float(lum.plane.max()) > knee * top


def widened_by_shoulder(
    answer: LocateResult,
    shouldered: LocateResult | None,
    knee: float,
    ruled_out: dict[str, str | float] | None,
    cfg: LocateConfig,
    measured_to: float | None = None,
) -> LocateResult:
    """``answer`` with its uncertainty widened (in quadrature) by its move to ``shouldered`` (the door located
    as if its camera had a shoulder from ``knee``, the cell's limits lifted), or refused ``uncertain`` where
    that takes it beyond the cell's limits, the refusal saying how to measure the response there
    (``measured_to``: the level the cell's photometric model read it up to; None: the cell has none); as it
    was where the door's arris strips or plain edges rule the shoulder out (``ruled_out``:
    :func:`shoulder_ruled_out`'s or :func:`plain_edges_rule_out`'s figure) or the shouldered reading was
    refused (None), the diagnostics saying which."""
    u = answer.uncertainty
    if u is None:
        return answer
    if shouldered is None or not shouldered.ok:
        answer.diagnostics["response_shoulder"] = {
            "knee": knee,
            "refused": None if shouldered is None else shouldered.error_code,
        }
        return answer
    move = {k: getattr(shouldered, k) - getattr(answer, k) for k in ("x_mm", "z_mm", "yaw_deg")}
    figure = {"knee": knee} | {f"move_{k}": round(v, 7) for k, v in move.items()}
    answer.diagnostics["response_shoulder"] = figure | (ruled_out or {})
    if ruled_out is not None:
        return answer
    widened = u.widened(move["x_mm"], move["z_mm"], move["yaw_deg"])
    answer.diagnostics.setdefault("uncertainty_budget", []).append(
        BudgetTerm(
            "response_shoulder", abs(move["x_mm"]), abs(move["z_mm"]), abs(move["yaw_deg"]), None
        ).as_dict()
    )
    if within_pose_limits(widened, cfg):
        answer.uncertainty = widened
        return answer
    exponent = _exponent_read(answer)
    read = (
        f" (its plain edges read the exponent {exponent:.2f} in place of the cell's "
        f"{answer.diagnostics['camera_response']['cell_gamma']:.2f}, as such a shoulder can make them read)"
        if exponent is not None
        else ""
    )
    measure = (
        "measure the camera's response beyond a power law once (doorloc calibrate --optics or doorloc "
        "check-model --boards write its photometric model into the calibration)"
        if measured_to is None
        else f"the calibration's board photographs read the camera's response up to {measured_to:.2f} of full "
        "scale only: measure it again on board photographs as bright as the door (doorloc calibrate --optics)"
    )
    return answer.refused(
        "uncertain",
        f"{uncertain_pose_words(widened, cfg)} with the doubt of the camera's response above {knee:g} of "
        f"full scale, which this image reaches{read}: a shoulder there would move it by x "
        f"{move['x_mm']:+.3f}, z {move['z_mm']:+.3f} mm; {measure} or expose the door darker",
    )


#: per kind of evidence, the misfit that says the plain reading describes the strips and the ratio over it
#: that rules the shoulder out: as an exponent is ruled out (:mod:`doorloc.vision.strip_response`)
_EVIDENCE = {
    "arc_misfit_over_free": (ARC_EXPLAINS, ARC_RULED_OUT),
    "chamfer_grey_misfit": (GREY_EXPLAINS, GREY_RULED_OUT),
}


def strip_misfit(fits: Iterable[StripFit], chamfered: bool) -> tuple[str, float] | None:
    """What a reading's arris strips ``fits`` say of the response it was read with: the chamfered strips'
    misfit in grey levels over the noise (:func:`doorloc.vision.strip_response.grey_score`), or the rounded
    strips' best matt arcs' misfit over their free shadings' (:func:`doorloc.vision.strip_response.
    arc_score`), as ``(kind, ratio)``; None where they say nothing (no strip, or none scored)."""
    fits = list(fits)
    if chamfered:
        key, score = "chamfer_grey_misfit", grey_score([f.grey_misfit for f in fits])
    else:
        arcs = [f.misfit_under_lights for f in fits if f.misfit_under_lights is not None]
        key, score = "arc_misfit_over_free", arc_score(arcs) if arcs else math.nan
    return (key, math.exp(score)) if math.isfinite(score) else None


def shoulder_ruled_out(
    plain: tuple[str, float] | None, shouldered: tuple[str, float] | None
) -> dict[str, str | float] | None:
    """Whether the door's arris strips rule the shoulder out: read through it, their misfit
    (:func:`strip_misfit` of the shouldered reading, ``shouldered``: rounded strips as matt arcs, chamfered
    ones in grey levels) is the ratio that rules an exponent out (1.25) times the plain reading's
    (``plain``), and the plain reading describes them (at most ``ARC_EXPLAINS`` or ``GREY_EXPLAINS``). The
    figure for the diagnostics where so (the evidence's kind and the ratio), else None (strips that fit
    either way alike, or none scored).

    Measured before it was built (the door located both ways, the cell stating the camera's exponent,
    knee 0.7; the strips read again at each answer's pose, ``diagnostics.response_from_strips`` at the
    cell's exponent, where the rule reads each answer's own strip fits): on power-law cameras (arris bench seeds 52016-57009, seven doors whose answers the shoulder's move took
    past the cell's limits) the chamfers' grey-level misfit rose 1.37-2.04 times and a lit rounding's arcs
    1.61 times; two roundings under light their arcs could not tell (every exponent alike) rose 1.00-1.01.
    On OpenCV's left camera's model (a shoulder from 0.69; bench_camera_doors seed 81000, door_012 and
    door_017) the chamfers' rose 1.06-1.07 times.
    """
    if plain is None or shouldered is None or plain[0] != shouldered[0]:
        return None
    key, explains, ruled_out = plain[0], *_EVIDENCE[plain[0]]
    if not (plain[1] <= explains and shouldered[1] >= ruled_out * plain[1]):
        return None
    return {"ruled_out_by": key, "misfit_ratio": round(shouldered[1] / plain[1], 3)}


def plain_edges_rule_out(shouldered: LocateResult) -> dict[str, str | float] | None:
    """Whether the door's plain edges rule the shoulder out: read through it (``shouldered``, the door located
    as if its camera had the cell's exponent and a shoulder from the knee), they still read another exponent
    than the cell's and it replaced the cell's there too (``diagnostics.camera_response.absorbed`` of that
    reading): the shoulder at the cell's exponent is not what the edges show. The figure for the diagnostics
    where so (the evidence's kind and the exponent read through the shoulder), else None.

    Measured before it was built: a linear camera with a shoulder from 0.55 (tests/vision/
    test_camera_response.py's, a door at 0.85 of full scale) read 1.42 and was answered 0.001 mm off; read
    through a shoulder from 0.7 at the cell's 1.0 its edges read 2.61 and replaced it again, the answer
    0.11 mm away (without this rule the door was refused for it). OpenCV's left camera's door_007 (above,
    a shoulder from 0.69): read through the shoulder, its edges read 0.99, the cell's own: not ruled out."""
    exponent = _exponent_read(shouldered)
    if exponent is None:
        return None
    return {"ruled_out_by": "plain_edges_exponent", "exponent_read": round(exponent, 4)}


def _exponent_read(answer: LocateResult) -> float | None:
    """The exponent an answer's plain edges read and put in the cell's place (its response check's
    ``diagnostics.camera_response``: ``absorbed``, the exponent as ``first_fit``), None where they did not."""
    response = answer.diagnostics.get("camera_response", {})
    return float(response["first_fit"]) if response.get("absorbed") and "first_fit" in response else None
