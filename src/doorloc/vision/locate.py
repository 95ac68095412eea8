"""Image -> door pose: the public :func:`locate` and its :class:`LocateConfig`.

The flow (thesis section 3.7, made metric and robust)::

    luminance -> size/exposure checks -> coarse steps in the search region (RANSAC lines)
      -> coarse pose on the hinge-face plane
      -> sub-pixel edge points along every scan line of each edge (area estimator), pass 1
         (beside a visible far face — a thin door shifted towards -X — the far arris instead by a
         fit of the profile's shape: hinge face | far-face band | background, two blurred steps,
         the band's width from the geometry, the blur measured on the reference arris)
      -> joint robust fit of bottom end + reference arris + far arris on the plane -> pose
      -> pass 2 with windows centred on the fitted lines and sized to the measured blur -> pose
      -> (a rounded door, no light stated: the light its strips fit best, and the passes again under it)
      -> each line's doubts -> the door's direction voted again, each line weighed by its whole doubt
      -> quality gate -> LocateResult
      -> (an arris door whose response the image could not check, or a door whose plain edges read an
         exponent in the cell's place, in a cell without its camera's photometric model, its image above
         the shoulder's knee: all of it again as if the camera had a shoulder, the move in the answer's
         uncertainty unless the strips or the plain edges rule the shoulder out)

As code, :func:`_locate` visits each stage once, each handing the next a frozen value
(:mod:`doorloc.vision.state`): the coarse stage (:func:`doorloc.vision.coarse_stage.find_coarse`, the
reasons of its refusals in :mod:`doorloc.vision.coarse_refusals`) -> :class:`~doorloc.vision.coarse_stage.Coarse`
-> the refine stage (:func:`doorloc.vision.refine.refine`: passes over the edge models of
:mod:`doorloc.vision.edge_models`) -> :class:`~doorloc.vision.state.Refined` -> the response check
(:func:`doorloc.vision.response_check.check_response`, which owns the absorb-and-rerun) ->
:class:`~doorloc.vision.state.ResponseCheck` (for a rounded door without a stated light, the refine stage
and the check again under the light of :func:`doorloc.vision.light_search.light_of_one_door`, the lit
answer given where it passes the gate, else the free shadings' answer or refusal) -> the doubts stage (:func:`doorloc.vision.doubts.edge_doubts`:
every line's doubts, typed) -> the direction's vote (:func:`doorloc.vision.direction_vote.voted_by_doubts`:
the pose again, each line's direction weighed by its whole doubt) -> the gate
(:func:`doorloc.vision.gate.gate_and_answer`: the checks, the
uncertainty from :func:`doorloc.vision.uncertainty.propagate`, the answer or the refusal); where a shoulder
is doubted (:mod:`doorloc.vision.response_shoulder`), :func:`_located` (every stage after the luminance)
runs a second time on the levels mapped through it.

:func:`locate` never raises for a bad image: every failure comes back as a refusal (``ok=false``,
``error_code``, ``error``). The codes: ``bad_image`` (not an 8/16-bit grey or colour array),
``wrong_image_size``, ``black_image``, ``saturated_image``, ``low_contrast``, ``no_door``, ``not_a_door``
(a regular pattern such as a calibration board), ``edge_missing``, ``edge_not_straight``, ``corner_hidden``,
``overexposed`` (the hinge face clips), ``sharpened`` (the camera sharpens its images), ``outside_envelope``,
``thickness_mismatch``, ``uncertain`` (the fit's standard error is too large, or the thickness's uncertainty
reaches past the tolerance) and ``internal_error`` (a bug: the message asks to keep the image).

Pass a :class:`LocateTrace` to keep what the pipeline saw, and give it to
:func:`doorloc.vision.overlay.draw_overlay` (which otherwise runs locate again).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, field, replace

import numpy as np

from doorloc import __version__
from doorloc.cell import Cell, DoorSize, edge_camera_cell
from doorloc.vision import quality as q
from doorloc.vision.arris_model import StripFit
from doorloc.vision.coarse import coarse_edges
from doorloc.vision.coarse_stage import StepQuery, find_coarse
from doorloc.vision.config import LocateConfig
from doorloc.vision.direction_vote import voted_by_doubts
from doorloc.vision.doubts import edge_doubts
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.far_band import FarFaceFit
from doorloc.vision.gate import gate_and_answer, uncertain_pose_words, within_pose_limits
from doorloc.vision.light_search import LightMeasurement, light_of_one_door
from doorloc.vision.luminance import ImageFormatError, LuminancePlane, camera_levels, luminance_plane
from doorloc.vision.metric import MetricPose
from doorloc.vision.mosaic import bayer_mosaic
from doorloc.vision.refine import refine
from doorloc.vision.region import EDGE_NAMES, Band, SearchRegion
from doorloc.vision.response_check import check_response
from doorloc.vision.response_shoulder import (
    doubted_knee,
    plain_edges_rule_out,
    shoulder_doubted,
    shoulder_ruled_out,
    shouldered_camera,
    strip_misfit,
    widened_by_shoulder,
)
from doorloc.vision.result import LocateResult, PhysicalModel, Provenance
from doorloc.vision.state import Refined, Refused, ResponseCheck, StageClock
from doorloc.vision.uncertainty import BudgetTerm

__all__ = ["LocateConfig", "locate", "locate_steps", "run_steps", "StepQuery", "LocateTrace"]


@dataclass
class LocateTrace:
    """What the pipeline saw, for the overlay and for debugging (not part of the JSON result)."""

    bands: dict[str, Band] = field(default_factory=dict)
    samples: dict[str, EdgeSamples] = field(default_factory=dict)
    inliers: dict[str, np.ndarray] = field(default_factory=dict)
    pose: MetricPose | None = None
    region: SearchRegion | None = None
    #: the final arris strip fits per line (rounded and chamfered arrises), as the uncertainty took them
    arris_fits: dict[str, StripFit] = field(default_factory=dict)
    #: the light the door's own rounded strips told (``locate.light_from_door``), None where not sought,
    #: and whether the answer was found under it (False: refused under it, the free shadings' outcome kept)
    door_light: LightMeasurement | None = None
    door_light_used: bool = False
    #: where the answer is the door's own light's and its strips did not single that light out: how far (x,
    #: z mm) the free shadings' pose lies from it, which its uncertainty took up (:func:`_lit_beside_free`)
    door_light_free_apart_mm: tuple[float, float] | None = None


def locate(
    image: np.ndarray,
    cell: Cell,
    door: DoorSize | None = None,
    *,
    image_name: str = "",
    config: LocateConfig | None = None,
    trace: LocateTrace | None = None,
    jpeg_quality: int = 0,
) -> LocateResult:
    """Find the door's reference corner, yaw and thickness in one image.

    Parameters
    ----------
    image : ndarray
        ``(H, W)`` grey or ``(H, W, 3|4)`` BGR(A), uint8 or uint16, as the camera delivered it; a colour
        image's channels are summed in light at the cell's exponent
        (:func:`doorloc.vision.luminance.luminance_plane`).
    cell : Cell
        Camera model, extrinsics, fixture and envelope.
    door : DoorSize, optional
        The door's nominal size (the cell's default door when None).
    image_name : str
        Copied to ``LocateResult.image``.
    config : LocateConfig, optional
        Thresholds; defaults when None.
    trace : LocateTrace, optional
        Filled with intermediate results (for :func:`doorloc.vision.overlay.draw_overlay`).
    jpeg_quality : int
        The libjpeg quality the image's file was stored at (:func:`doorloc.vision.imageio.stored_jpeg_quality`),
        0 where it was not a JPEG or is not known: the JPEG doubt then rests on the blocks the image shows.

    Returns
    -------
    LocateResult
        ``ok=true`` with ``x_mm``, ``z_mm``, ``yaw_deg``, ``thickness_mm`` (cell frame, mm/deg),
        ``scale_mm_per_px`` and ``corner_px``; or ``ok=false`` with ``error_code`` and ``error``.
    """
    return run_steps(
        locate_steps(
            image, cell, door, image_name=image_name, config=config, trace=trace, jpeg_quality=jpeg_quality
        ),
        coarse_edges,
    )


StepFinder = Callable[..., tuple[np.ndarray, np.ndarray]]


def run_steps(
    steps: Generator[StepQuery, tuple[np.ndarray, np.ndarray], LocateResult], finder: StepFinder
) -> LocateResult:
    """Run a :func:`locate_steps` coroutine to its answer, each step search by ``finder(plane, **kwargs)``.

    A finder that raises has its exception thrown into the coroutine, which answers with a refusal
    (``internal_error``) as for any other failure inside locate.
    """
    try:
        query = next(steps)
        while True:
            try:
                found = finder(query.plane, **query.kwargs)
            except Exception as e:  # noqa: BLE001 - handed to locate's own handling
                query = steps.throw(e)
                continue
            query = steps.send(found)
    except StopIteration as done:
        return done.value


def locate_steps(
    image: np.ndarray,
    cell: Cell,
    door: DoorSize | None = None,
    *,
    image_name: str = "",
    config: LocateConfig | None = None,
    trace: LocateTrace | None = None,
    luminance: LuminancePlane | None = None,
    jpeg_quality: int = 0,
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], LocateResult]:
    """:func:`locate` as a coroutine that hands out its coarse step searches.

    It yields a :class:`StepQuery` for each step search and expects ``(along, strength)`` as
    :func:`doorloc.vision.coarse.coarse_edges` would return them; it returns the :class:`LocateResult`.
    :func:`locate` answers the queries one by one; :mod:`doorloc.vision.batched` collects the queries of
    many images and answers them together. ``luminance``: the image's luminance when the caller has
    already made it (``image`` is then not read).
    """
    t0 = time.perf_counter()
    cfg = config or cell.locate
    door = door or cell.default_door
    tr = trace if trace is not None else LocateTrace()
    try:
        res = yield from _locate(image, cell, door, cfg, tr, image_name, luminance, jpeg_quality)
    except Refused as r:
        res = LocateResult.refusal(
            image_name,
            r.refusal.code,
            r.refusal.message,
            lines=r.diag.get("lines", []),
            diagnostics=r.diag.get("diagnostics", {}),
        )
    except Exception as e:  # noqa: BLE001 — a locate call must answer, never crash the caller
        # a bug: logged at error level with its traceback under an incident id that the answer quotes
        import logging
        import uuid

        incident = uuid.uuid4().hex[:12]
        logging.getLogger("doorloc.vision").error(
            "locate failed",
            exc_info=True,
            extra={"fields": {"event": "internal_error", "incident_id": incident, "image": image_name}},
        )
        res = LocateResult.refusal(
            image_name,
            "internal_error",
            f"locate failed on this image ({type(e).__name__}: {e}); keep the image and "
            f"report it with incident id {incident}",
            incident_id=incident,
        )
    if not res.ok and res.error_code not in ("bad_image", "wrong_image_size", "internal_error"):
        mosaic = _mosaic_named(image if luminance is None else luminance.plane, res.error or "")
        if mosaic is not None:
            res.error_code, res.error = mosaic.code, mosaic.message
    res.provenance = Provenance(
        version=__version__, cell_sha256=cell.sha256, calibration_sha256=cell.calibration_sha256
    )
    res.model = PhysicalModel(
        response_gamma=cell.response_gamma,
        response_gamma_sigma=cell.response_gamma_sigma,
        stored_bits=cell.stored_bits,
        arris_mm=door.arris_mm,
        arris_profile=door.arris_profile,
        door_brighter=cfg.door_brighter,
        face_y_mm=cell.face_y(door),
        **_light_echo(cfg, tr.door_light if tr.door_light_used else None),
        camera_photometry=cell.camera_photometry.locate_parameters()
        if cell.camera_photometry is not None
        else None,
    )
    if tr.door_light is not None:
        res.diagnostics["door_light"] = _door_light_diagnostics(
            tr.door_light, tr.door_light_used, tr.door_light_free_apart_mm
        )
    res.elapsed_ms = (time.perf_counter() - t0) * 1e3
    return res


def _mosaic_named(image, reason: str) -> q.Refusal | None:
    """Where a refused image (``reason``: why) is a colour camera's raw Bayer mosaic read as grey
    (:func:`doorloc.vision.mosaic.bayer_mosaic`), the refusal that says so, the other reason following from
    it; else None. Read only on a refused image (a few ms a 1080p frame)."""
    mosaic = bayer_mosaic(image)
    if mosaic is None:
        return None
    return q.Refusal(
        "bad_image",
        "the image is a single-chip colour camera's raw Bayer mosaic: its pixel sites alternate in level "
        f"(in each 2 x 2 block the first row's red-or-blue site reads {100 * mosaic.first:+.0f} %, the "
        f"second row's {100 * mosaic.second:+.0f} % against the two green sites); set the camera to deliver "
        "grey (Mono8, Mono12) or demosaiced colour (BGR8), or demosaic its frames before locating them "
        f"(read as grey, locate found: {reason})",
    )


def _light_echo(cfg: LocateConfig, own: LightMeasurement | None) -> dict:
    """The light the rounded arrises were shaded under, for ``LocateResult.model``: the cell's, the door's
    own, or none."""
    if cfg.light_direction_deg is not None:
        return dict(
            light_direction_deg=list(cfg.light_direction_deg),
            light_direction_sigma_deg=cfg.light_direction_sigma_deg,
            light_source="cell",
        )
    if own is not None:
        return dict(
            light_direction_deg=list(own.direction_deg),
            light_direction_sigma_deg=own.sigma_deg,
            light_source="door",
        )
    return {}


def _locate(
    image,
    cell: Cell,
    door: DoorSize,
    cfg: LocateConfig,
    tr: LocateTrace,
    name: str,
    lum: LuminancePlane | None = None,
    jpeg_quality: int = 0,
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], LocateResult]:
    try:
        stored = lum if lum is not None else luminance_plane(image, cell.response_gamma, cell.stored_bits)
    except ImageFormatError as e:
        raise Refused(q.Refusal("bad_image", f"{e}")) from None
    res = yield from _located(stored, cell, door, cfg, tr, name, jpeg_quality)
    measured = cell.camera_photometry
    knee = doubted_knee(cfg.response_shoulder_knee, measured)
    if not shoulder_doubted(res, stored, knee, door.arris_mm):
        return res
    # located again as if the camera had a shoulder from the knee (its own trace: this answer is asked, not
    # given), the cell's limits lifted: the move is the answer's doubt (doorloc.vision.response_shoulder)
    shouldered_cell = replace(cell, camera_photometry=shouldered_camera(cell.response_gamma, knee, measured))
    bent = LocateTrace()
    try:
        shouldered = yield from _located(
            stored, shouldered_cell, door, _limits_lifted(cfg), bent, name, jpeg_quality
        )
    except Refused:
        shouldered = None
    chamfered, ruled_out = door.arris_profile == "chamfer", None
    if shouldered is not None and shouldered.ok:
        ruled_out = shoulder_ruled_out(
            strip_misfit(tr.arris_fits.values(), chamfered), strip_misfit(bent.arris_fits.values(), chamfered)
        ) or plain_edges_rule_out(shouldered)
    return widened_by_shoulder(
        res, shouldered, knee, ruled_out, cfg, None if measured is None else measured.response_measured_to
    )


def _located(
    stored: LuminancePlane,
    cell: Cell,
    door: DoorSize,
    cfg: LocateConfig,
    tr: LocateTrace,
    name: str,
    jpeg_quality: int,
) -> Generator[StepQuery, tuple[np.ndarray, np.ndarray], LocateResult]:
    """The answer from the image's stored luminance ``stored``, its levels mapped through the cell's
    photometric model where it has one (:func:`doorloc.vision.luminance.camera_levels`)."""
    lum = camera_levels(stored, cell.camera_photometry, cell.response_gamma)
    r = q.check_image_size(lum.size, cell.camera.image_size)
    if r:
        raise Refused(r)
    plane, s8 = lum.plane, lum.scale_to_8bit
    cell = edge_camera_cell(cell)
    clock = StageClock()
    region = SearchRegion.cached(cell, door, cfg.search_margin_mm, cfg.search_margin_deg, cfg.door_brighter)
    tr.region = region
    clock.lap("region")
    coarse = yield from find_coarse(lum, region, cell, door, cfg, clock, tr.bands)

    def refined_and_checked(c: LocateConfig) -> ResponseCheck:
        """The refine stage from the coarse pose and the response check (which may refine again), under ``c``."""
        first = refine(plane, s8, region, coarse.pose, c, clock, cell.response_gamma)
        return check_response(
            plane, cell, c, first, lambda start, gamma: refine(plane, s8, region, start, c, clock, gamma), s8
        )

    check = refined_and_checked(cfg)
    own = _door_light(cfg, check.refined)
    if own is None:
        return _answer(name, door, cfg, region, check, lum, clock, tr, jpeg_quality)
    clock.lap("door_light")
    # Located again under the door's own light, as if the cell stated it. Where that answer is refused (a
    # light the strips tell wrong widens their doubt), the free shadings' outcome stands, their answer or
    # their refusal: each is judged by its own uncertainty, neither is chosen by its error, and a door the
    # free shadings refused keeps their reason; their answer stands only near the lit pose
    # (:func:`_free_beside_lit`). (The free outcome is gated only then: its doubts cost as much as the lit
    # answer's, and a lit answer that passes needs no other, but where the strips did not single the light
    # out and the free shadings' distance takes it past the limits, :func:`_lit_beside_free`.)
    lit_cfg = replace(cfg, light_direction_deg=own.direction_deg, light_direction_sigma_deg=own.sigma_deg)
    tr.door_light, tr.door_light_used = own, True
    lit_pose = None
    try:
        lit = refined_and_checked(lit_cfg)
        res = _answer(name, door, lit_cfg, region, lit, lum, clock, tr, jpeg_quality)
        if res.ok:

            def free_sigma() -> tuple[float, float] | None:
                # (a trace of its own: the free shadings' answer is asked, not given)
                return _free_sigma(
                    lambda c: _answer(name, door, c, region, check, lum, clock, LocateTrace(), jpeg_quality),
                    cfg,
                )

            return _lit_beside_free(res, lit.refined.pose, check.refined.pose, free_sigma, own, cfg, tr)
        lit_pose = res.diagnostics.get("measured")
    except Refused:
        pass
    tr.door_light_used = False
    return _free_beside_lit(
        _answer(name, door, cfg, region, check, lum, clock, tr, jpeg_quality), lit_pose, own
    )


#: the free shadings' answer stands beside the door's own light's (refused) pose only within this many of
#: its own sigmas in x and z
SHADINGS_APART_SIGMAS = 3.0


def _free_beside_lit(free: LocateResult, lit: dict | None, own: LightMeasurement) -> LocateResult:
    """The free shadings' answer, or a refusal where the pose located under the door's own light (refused:
    ``lit``, its measured pose) lies more than ``SHADINGS_APART_SIGMAS`` of the answer's sigmas from it in
    x or z. The two read the same pixels with two models of the rounded strips' shading; where they place
    the door that far apart the answer's sigma, which holds only its own model's doubts, understates what
    the image leaves open (`bench_arris_range.py --sets defocus --seed 55000 --cell-gamma-off bound`, door
    66005: the free shadings answered z +0.41 mm off at sigma 0.027; the door's light placed it 0.05 mm
    off at sigma 0.28, refused)."""
    if not free.ok or lit is None or free.uncertainty is None:
        return free
    u = free.uncertainty
    dx, dz = abs(free.x_mm - lit["x_mm"]), abs(free.z_mm - lit["z_mm"])
    if max(dx / max(u.x_mm, 1e-9), dz / max(u.z_mm, 1e-9)) <= SHADINGS_APART_SIGMAS:
        return free
    az, el = own.direction_deg
    return free.refused(
        "uncertain",
        f"the door's rounded arrises read two ways: shaded freely they place the door at x {free.x_mm:+.3f}, z "
        f"{free.z_mm:+.3f} mm, under the light their shading tells (azimuth {az:.0f}, elevation {el:.0f} deg) "
        f"at x {lit['x_mm']:+.3f}, z {lit['z_mm']:+.3f} mm, further apart than the answer's uncertainty (x "
        f"{u.x_mm:.3f}, z {u.z_mm:.3f} mm); state the cell's light (locate.light_direction_deg) and its "
        "camera's measured response (doorloc calibrate, or doorloc measure-light --response from a few doors), "
        "or light the arrises from one known direction",
    )


def _free_sigma(
    free_answer: Callable[[LocateConfig], LocateResult], cfg: LocateConfig
) -> tuple[float, float] | None:
    """The free shadings' own 1-sigma of x and z (mm): their answer (``free_answer``, :func:`_answer` on
    their response check) under ``cfg`` with the cell's limits lifted; None where they give none (refused
    for another reason)."""
    try:
        free = free_answer(_limits_lifted(cfg))
    except Refused:
        free = None
    u = free.uncertainty if free is not None and free.ok else None
    return None if u is None else (u.x_mm, u.z_mm)


def _limits_lifted(cfg: LocateConfig) -> LocateConfig:
    """``cfg`` without the cell's limits on the answer's uncertainty and its thickness's verification: for
    another reading of the door, whose pose is asked rather than judged."""
    return replace(
        cfg,
        max_uncertainty_mm=math.inf,
        max_uncertainty_deg=math.inf,
        max_sigma_mm=math.inf,
        thickness_check="report",
    )


def _lit_beside_free(
    lit: LocateResult,
    lit_pose: MetricPose,
    free_pose: MetricPose,
    free_sigma: Callable[[], tuple[float, float] | None],
    own: LightMeasurement,
    cfg: LocateConfig,
    tr: LocateTrace,
) -> LocateResult:
    """The answer found under the door's own light, ``lit``, where the door's strips do not single that
    light out (:attr:`LightMeasurement.tells_one_direction`): its uncertainty widened (in quadrature) by half
    the distance of the free shadings' pose from it; where that takes it beyond the cell's limits, refused
    ``uncertain`` unless the free shadings' own 1-sigma (``free_sigma``, asked only then) holds the
    distance. ``lit_pose``, ``free_pose``: the two refine stages' poses (before the doubts' votes on the
    direction), which read the same pixels with two models of the rounded strips' shading.

    Where the strips fit other directions about as well, the light is a guess, and the answer under it
    rests on that guess as much as on the image: the free shadings, which assume no light, are the other
    reading (as two models of one strip weighed alike spread its deficit by half their difference,
    :func:`doorloc.vision.strip_posterior.valley_posterior`; the other reading then lies within 2 sigma of
    the answer). Where the free shadings' own doubt holds the difference, it is their reading that is
    uncertain, and the answer stands as it was. Measured: ``bench_arris_range.py --n 32 --seed 10100
    --response-factor 1.11`` (a cell whose response was measured), door 10124, a 1.01 mm rounding lit from
    azimuth +68, elevation -21: its strips told [-40, +10] with a runner-up at [+60, +60] and half the
    first grid alike, and it was answered 0.178 mm off in x at a sigma of 0.093, where the free shadings
    placed it 0.032 mm off at a sigma of 0.151; 0.21 mm apart, it is now refused. That bench: 121 -> 120 of
    128 answered, the round set's x RMS 0.033 -> 0.007 mm, the worst x error 1.9 -> 0.7 sigma (at seed 9100
    117 -> 116, a right answer lost). Where the
    response is not measured (the cell's factor) ``--seed 9100`` and ``--seed 10100`` answer the same doors
    as before; ``bench_surfaces.py --sets combined --seed 47000`` (grain, gradients, JPEG) lost door 14, a
    2.49 mm rounding answered 0.008 mm off, whose free shadings lay 0.54 mm away at 6.7 of their own sigmas.
    The free shadings' doubt is asked only beyond the limits: counting their doubts once more costs 0.3-1.2 s
    on a rounded door (about half its locate)."""
    u = lit.uncertainty
    if own.tells_one_direction or u is None:
        return lit
    dx, dz = abs(lit_pose.x_mm - free_pose.x_mm), abs(lit_pose.z_mm - free_pose.z_mm)
    dyaw = abs(lit_pose.yaw_deg - free_pose.yaw_deg)
    tr.door_light_free_apart_mm = (dx, dz)
    # half the difference: the free shadings' reading then lies within 2 sigma of the answer whatever the
    # answer's own sigma (the product's test of an honest sigma), as two models weighed alike spread by it
    widened = u.widened(0.5 * dx, 0.5 * dz, 0.5 * dyaw)
    if within_pose_limits(widened, cfg):
        lit.uncertainty = widened
        lit.diagnostics.setdefault("uncertainty_budget", []).append(
            BudgetTerm("door_light", 0.5 * dx, 0.5 * dz, 0.5 * dyaw, None).as_dict()
        )
        return lit
    # Beyond the limits, the free shadings' own doubt is asked (their doubts counted once more, 0.3-1.2 s
    # on a rounded door, so only here): where it holds the difference they do not dispute the answer (their
    # reading, not the lit one, is then the uncertain one), and the answer stands as it was
    free = free_sigma()
    if free is not None and dx <= free[0] and dz <= free[1]:
        return lit
    az, el = own.direction_deg
    return lit.refused(
        "uncertain",
        f"the door's rounded arrises read two ways: under the light their shading tells best (azimuth "
        f"{az:.0f}, elevation {el:.0f} deg, though other directions fit them about as well) they place the "
        f"door at x {lit.x_mm:+.3f}, z {lit.z_mm:+.3f} mm, shaded freely {dx:.3f} mm and {dz:.3f} mm from "
        f"there: {uncertain_pose_words(widened, cfg)}; state the cell's light (locate.light_direction_deg, which "
        "doorloc measure-light measures from images of its doors) and its camera's measured response, or "
        "light the arrises from one known direction",
    )


def _trace_refined(tr: LocateTrace, refined: Refined) -> None:
    """Keep the refine stage's edges, inliers, pose and strip fits in the trace."""
    tr.samples = refined.samples
    tr.inliers = {k: refined.fit.weights[k] > 0 for k in EDGE_NAMES}
    tr.pose = refined.pose
    tr.arris_fits = {k: strip for k, (strip, _) in refined.arris_fits.items()}


def _answer(
    name: str,
    door: DoorSize,
    cfg: LocateConfig,
    region: SearchRegion,
    check: ResponseCheck,
    lum: LuminancePlane,
    clock: StageClock,
    tr: LocateTrace,
    jpeg_quality: int,
) -> LocateResult:
    """The doubts and the gate after the response check: the answer, or :class:`Refused`."""
    # why many parameters: the stages' values that the doubts and the gate read, passed as they are
    doubts = edge_doubts(lum.plane, lum.scale_to_8bit, region, cfg, check, jpeg_quality, lum.level_8bit)
    refined, spread = voted_by_doubts(check.refined, region, doubts.model)
    if cfg.direction_check and spread is not None and spread.doubts:
        doubts = replace(doubts, model=doubts.model.with_doubts(*spread.doubts))
    _trace_refined(tr, refined)
    check = replace(check, refined=refined)
    res = gate_and_answer(name, door, cfg, region, check, doubts, lum)
    if spread is not None:
        res.diagnostics["direction_spread"] = spread.figure()
    res.diagnostics["camera_response"] = check.diagnostics
    res.diagnostics["far_face_visible"] = refined.far_beside
    if refined.direction_votes:
        total = sum(refined.direction_votes.values())
        res.diagnostics["direction_votes"] = {
            k: round(v / total, 4) for k, v in refined.direction_votes.items()
        }
    if refined.far_fit is not None:
        res.diagnostics["far_face_fit"] = _far_face_diagnostics(refined.far_fit)
    clock.lap("gate")
    res.diagnostics["timing_ms"] = clock.laps
    return res


def _door_light(cfg: LocateConfig, refined: Refined) -> LightMeasurement | None:
    """The light the door's own rounded strips tell (``locate.light_from_door``), where the cell states
    none; None where the light is stated or not sought, or no strip is a rounding's (only a rounding's
    strip fit carries ``misfit_under_lights``: a chamfer's, or a door without an arris, has none)."""
    if cfg.light_direction_deg is not None or not cfg.light_from_door:
        return None
    fits = [strip.misfit_under_lights for strip, _ in refined.arris_fits.values()]
    return light_of_one_door([f for f in fits if f is not None])


def _door_light_diagnostics(
    light: LightMeasurement, used: bool, free_apart_mm: tuple[float, float] | None
) -> dict:
    """The door's own light as the result's diagnostics report it, whether the answer is the one found
    under it (``used``; False: it was refused under it, and the free shadings' outcome stands), and how
    far the free shadings' pose lay from it where the strips did not single the light out (x, z mm)."""
    return (
        {
            "used": used,
            "direction_deg": [round(v, 1) for v in light.direction_deg],
            "sigma_deg": light.sigma_deg,
            "misfit_over_free": round(math.exp(light.score), 4),
            "directions_alike_share": round(light.alike_share, 3),
            "strips": light.strips,
        }
        | ({"runner_up_deg": list(light.runner_up_deg)} if light.runner_up_deg is not None else {})
        | ({"free_apart_mm": [round(v, 4) for v in free_apart_mm]} if free_apart_mm is not None else {})
    )


def _far_face_diagnostics(far_fit: FarFaceFit) -> dict[str, float | str]:
    """The far-face fit as the result's diagnostics report it (rounded)."""
    figures: dict[str, float | str] = {
        "band_level": round(far_fit.band_level, 4),
        "blur_px": round(far_fit.blur_px, 3),
        "band_px": round(far_fit.band_px, 3),
        "arris_sigma_px": round(far_fit.arris_sigma_px, 4),
        "model_sigma_px": round(far_fit.model_sigma_px, 4),
        "other_reading_px": round(far_fit.other_reading_px, 3),
        "other_fitted": far_fit.other_fitted,
    }
    if math.isfinite(far_fit.strip_level):
        figures["strip_level"] = round(far_fit.strip_level, 4)
    return figures
