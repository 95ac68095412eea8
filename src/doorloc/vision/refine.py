"""The refine stage of locate: sub-pixel edge points along every scan line of each edge and the joint line
fit, in passes (the first, on every fifth scan line, centres and sizes the final windows; beside a far face
one more, and one more where a line read as a plain step kept fewer than ``PLAIN_LINES_KEPT_SHARE`` of its
points: a stripe of grain beside an arris can pull the first pass's area estimates several pixels into the
face, and the final windows centred there miss the edge, while the fit of the points they keep places it).
Each edge is read by the model its kind names (:mod:`doorloc.vision.edge_models`); what the stage finds is
a :class:`doorloc.vision.state.Refined`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from doorloc.cell import DoorSize
from doorloc.pose import direction_cell
from doorloc.vision import quality as q
from doorloc.vision.arris_geometry import ArrisGeometry
from doorloc.vision.arris_model import StripFit, arris_geometry
from doorloc.vision.config import LocateConfig
from doorloc.vision.edge_models import (
    ARRIS_PLATEAU_PX,
    EDGE_MODELS,
    PassSettings,
    ReadersApart,
    ScanWindow,
    edge_kind,
)
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.far_band import FarFaceFit
from doorloc.vision.lines import RectangleFit, fit_rectangle_edges
from doorloc.vision.metric import MetricPose, pose_from_fit
from doorloc.vision.region import EDGE_NAMES, HUMAN, SearchRegion
from doorloc.vision.sampling import linearizing_lut
from doorloc.vision.state import Refined, Refused, StageClock
from doorloc.vision.stated_light import StatedLight
from doorloc.vision.step_blur import step_blur
from doorloc.vision.step_fit_lines import step_fit_lines
from doorloc.vision.strip_posterior import strip_blur_priors
from doorloc.vision.strip_response import StripReadings, arc_score, grey_score
from doorloc.vision.thickness_gate import shows_one_step
from doorloc.vision.transition import narrowest_blur, transition_width

__all__ = ["arris_response_shifts", "refine"]

#: how far (a fraction of the strip's width) a first-pass strip fit's best reading may lie from its
#: posterior's mean before its two plain-step readings count as both in play (:func:`_held_to_first_pass`)
READINGS_GAP = 0.25
#: the first pass's posterior spread (sd of the deficit) at which a best reading that is one plain step
#: leaves its other reading in play, however little the mean moved (:func:`_held_to_first_pass`): a posterior
#: split between two readings a deficit of 1 apart, a share ``q`` on the other, has the sd sqrt(q (1 - q)):
#: 0.2 is a share of about 4 %
READINGS_SPREAD = 0.2
#: the edge models that read a line as a plain step (no strip or band beside it)
PLAIN_STEP_KINDS = ("plain", "step_fit")
#: the share of its scan lines a plain step's final pass must keep, else its windows are taken as centred
#: off its edge and the refine stage reads every line once more at the pose the pass fitted
#: (:func:`_plain_lines_lost`)
PLAIN_LINES_KEPT_SHARE = 0.7
#: scan lines on which the reference arris's own blur is read where the blur the step fits would use, from
#: transitions that noise widens, is checked (:func:`doorloc.vision.step_fit_lines.step_fit_lines`) and no
#: far face needs it read on more. On a sharp (0.24 px) door whose noisy draws' widths read 0.46-0.69 px of
#: optical blur it read 0.05-0.13 px (:func:`doorloc.vision.step_blur.step_blur`), and noise does not move
#: it above 0.5 px (0.6 / 0.8 / 1.2 px read 0.59-0.60 / 0.82 / 1.21-1.22 at 0.5 and 2 grey levels); 40 scan
#: lines read it within 0.03 px of 160's, in 0.7 ms instead of 1.7
STEP_FIT_CHECK_LINES = 40
#: a plain reference arris's step blur this many times the narrowest first-pass transition's blur or more
#: is texture's, not the lens's (:func:`_within_narrowest`; the step fits' own rule for a transition that
#: carries more than a step, :func:`doorloc.vision.step_fit_lines.step_fit_lines`)
OPTICAL_BLUR_NARROW_FACTOR = 1.25
#: the arris lines whose reading nothing else checks: the reference and far arrises' readings are held to
#: the recipe's thickness (a strip's width off on one side is a thickness that far off), the bottom end's
#: to nothing
READINGS_UNCHECKED = ("bottom",)


@dataclass(frozen=True)
class _Sampled:
    """Edge points of one pass: per line, whether a far face was beside the far arris, its fit, and the
    lines whose points the blurred-step fit refined (name -> the blur it used, px) and, where it was tried,
    how far its points lay from the area estimator's; the lines it read with the face sloped (name -> its
    window's half width, px); the lines read as plain steps (no strip or band beside them)."""

    samples: dict[str, EdgeSamples]
    far_beside: bool
    far_fit: FarFaceFit | None
    step_fitted: dict[str, float]
    readers_apart: dict[str, ReadersApart]
    face_sloped: dict[str, int]
    plain_steps: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Pass:
    """What one pass of the refine stage changes: the window's half width ``half`` (px), every n-th scan line
    read (``every``), whether the edges are sharper than the windows assume (``sharp``), the optical blur
    measured on the reference arris (``optical_blur_px``, NaN before it is) and the lines the blurred-step fit
    refines with the blur it uses (``step_fit``, px); the edges it reads (``lines``: all three but where the
    arris lines are read again) and whether their strips' doubts are read (``strip_doubts``: not where they
    are read again at trial exponents); ``blur_priors`` per arris line the blur the other strips read on
    the pass before (mean, sd px: :func:`doorloc.vision.strip_posterior.strip_blur_priors`);
    ``face_slope_blur_px`` the blur from which a long arris under strong texture is read with its face
    sloped (NaN: none is)."""

    half: int
    every: int = 1
    sharp: bool = False
    optical_blur_px: float = float("nan")
    step_fit: dict[str, float] | None = None
    face_slope_blur_px: float = float("nan")
    lines: tuple[str, ...] = EDGE_NAMES
    strip_doubts: bool = True
    blur_priors: dict[str, tuple[float, float]] = field(default_factory=dict)


def _arris_and_keep(
    region: SearchRegion, pose: MetricPose, half: int, cfg: LocateConfig
) -> tuple[dict[str, ArrisGeometry] | None, int]:
    """The arris strips' geometry per line at ``pose`` (None without an arris) and how far from the corners
    (px) the scan lines stay: the window, its plateaus and 4 px, and with an arris its strip's width."""
    keep = half + cfg.plateau + 4
    door = region.door
    geoms = (
        arris_geometry(
            door.arris_mm,
            door.arris_profile,
            region.plane_map.centre,
            pose.corner,
            pose.yaw_deg,
            region.face_y,
            pose.thickness_mm,
        )
        if door.arris_mm > 0
        else None
    )
    if geoms:
        # Near a corner the other edge's arris strip (about the arris wide from the sharp corner) crosses
        # the scan lines: the strip's profile fit would see two strips there and misfit. Keep its width
        # (and the strip fit's wider plateaus) clear of the corners.
        keep = (
            half
            + max(cfg.plateau, ARRIS_PLATEAU_PX)
            + 4
            + int(math.ceil(door.arris_mm / region.nominal_scale))
        )
    return geoms, keep


def _stated_light(cfg: LocateConfig) -> StatedLight | None:
    """The cell's light as its ``locate`` section states it, or None where it states none."""
    if cfg.light_direction_deg is None:
        return None
    return StatedLight(direction_cell(*cfg.light_direction_deg), math.radians(cfg.light_direction_sigma_deg))


def _sample(
    plane,
    scale8: float,
    region: SearchRegion,
    pose: MetricPose,
    cfg: LocateConfig,
    this_pass: _Pass,
    response_gamma: float = 1.0,
    arris_fits: dict[str, tuple[StripFit, float]] | None = None,
) -> _Sampled:
    """One pass's edge points on its edges (``this_pass.lines``) at ``pose``, each read by the model of its
    kind; ``scale8`` turns ``plane``'s grey levels to 0-255, ``response_gamma`` them to light; each line's
    arris strip fit goes into ``arris_fits``."""
    half, every = this_pass.half, this_pass.every
    yaw_rad = math.radians(pose.yaw_deg)
    lut = linearizing_lut(plane.dtype, response_gamma)
    door = region.door
    geoms, keep = _arris_and_keep(region, pose, half, cfg)
    # An arris door's thickness measured on a first pose can be up to the strip's width short (its inner
    # border taken for the edge): whether the far face is in view is decided at the recipe's thickness
    # then (arris bench seed 7558: a 2.5 mm rounding, the camera 1.2 mm inside the far face's plane, seen
    # as beside it from a pose 2.6 mm thin: the far arris lost)
    tracks = region.tracks(
        pose.corner,
        yaw_rad,
        pose.thickness_mm,
        keep,
        window_px=half + cfg.plateau + 2,
        arris=geoms,
        visibility_thickness_mm=max(pose.thickness_mm, door.thickness_mm) if geoms else None,
    )
    settings = PassSettings(
        every=every,
        sharp=this_pass.sharp,
        optical_blur_px=this_pass.optical_blur_px,
        slope_smooth=max(cfg.slope_smooth // every, 1) if cfg.slope_smooth else 0,
        door=door,
        arris=geoms,
        step_blur_px=this_pass.step_fit or {},
        light=_stated_light(cfg),
        strip_doubts=this_pass.strip_doubts,
        strip_blur_priors=this_pass.blur_priors,
        face_slope_blur_px=this_pass.face_slope_blur_px,
    )
    out, far_fit, step_fitted, apart, sloped = {}, None, {}, {}, {}
    plain_steps = []
    for name in this_pass.lines:
        lay, t = region.layouts[name], tracks[name]
        window = ScanWindow(
            plane,
            lay.axis,
            t.scan[::every],
            t.centre[::every],
            half,
            cfg.plateau,
            scale8,
            lut,
            level_smooth=max(cfg.level_smooth // every, 1) if cfg.level_smooth else 0,
            door_side=lay.door_side(cfg.door_brighter),
        )
        kind = edge_kind(name, t, settings)
        reading = EDGE_MODELS[kind].read(window, name, t, settings)
        out[name] = reading.samples
        if kind in PLAIN_STEP_KINDS:
            plain_steps.append(name)
        if reading.far_fit is not None:
            far_fit = reading.far_fit
        if reading.strip is not None and arris_fits is not None:
            arris_fits[name] = reading.strip
        if reading.step_blur_px is not None:
            step_fitted[name] = reading.step_blur_px
        if reading.readers_apart is not None:
            apart[name] = reading.readers_apart
        if reading.face_slope_half_px is not None:
            sloped[name] = reading.face_slope_half_px
    return _Sampled(
        out, tracks["far"].beside_far_face, far_fit, step_fitted, apart, sloped, tuple(plain_steps)
    )


def _fit(
    samples: dict[str, EdgeSamples],
    region: SearchRegion,
    cfg: LocateConfig,
    every: int = 1,
    n_iter: int = 9,
    far_offset_only: bool = False,
    centring: bool = False,
) -> tuple[RectangleFit, dict[str, tuple[np.ndarray, bool]]]:
    """The joint line fit of one pass's edge points (``every``-th of each line's), robust (Tukey IRLS,
    ``n_iter`` iterations), with the points of the expected polarity and contrast; ``centring``: the fit
    only centres the next pass's windows (see below). And the lines' points as fitted (``(X, Z)`` mm on
    the outline plane, 0 where a point has none; whether the line runs along door X)."""
    groups, init = {}, {}
    subsets = {
        name: samples[name].subset(np.arange(samples[name].scan.size) % every == 0)
        if every > 1
        else samples[name]
        for name in EDGE_NAMES
    }
    # all edge points back-projected in one call (point by point: the same numbers, less overhead)
    xz_all = region.plane_points(np.concatenate([subsets[name].uv() for name in EDGE_NAMES]))
    first = 0
    for name in EDGE_NAMES:
        s = subsets[name]
        xz = xz_all[first : first + s.scan.size]
        first += s.scan.size
        pol = region.layouts[name].polarity
        if name == "far" and far_offset_only:  # beside the far face: either polarity
            pol = int(np.sign(np.nanmedian(s.step))) or pol
        finite = np.isfinite(xz)
        good = s.valid & (s.located_contrast(pol, cfg.min_contrast) >= 0.5 * cfg.min_contrast)
        good &= finite.all(axis=1)
        if np.count_nonzero(good) < 3:
            raise Refused(q.Refusal("edge_missing", _missing_edge_reason(name, s, cfg.min_contrast)))
        groups[name] = (np.where(finite, xz, 0.0), region.layouts[name].along_x)
        init[name] = good.astype(float)
    offset_only = ("far",) if far_offset_only else ()
    try:
        fit = fit_rectangle_edges(
            groups, scale_floor=1e-4, init_weights=init, n_iter=n_iter, offset_only=offset_only
        )
    except ValueError as e:  # a line lost all its points to the robust weights
        if centring:
            # The Tukey weights judge every line on one pooled residual scale. The first pass reads the far
            # arris's strip by its area estimate (edge_models.ArrisStrip: the strip's line fit there can take
            # another level than the final pass), whose levels are single samples beside a window up to 40 px
            # long: on an 8-bit face it scatters by +-0.4 px where the lines read by the strip's line fit
            # scatter by 0.01 px, and the pooled scale drops every far point (arris range bench, chamfer
            # seed 8314). Huber's weights (the first three iterations) cannot drop a line, and a fit that
            # only centres the next windows needs no more; the final pass reads every line by its model.
            fit = fit_rectangle_edges(
                groups, scale_floor=1e-4, init_weights=init, n_iter=3, offset_only=offset_only
            )
            return fit, groups
        raise Refused(
            q.Refusal(
                "edge_missing",
                f"the door's edges do not fit a rectangle ({e}); check that the "
                "door lies in the fixture and nothing covers its edges",
            )
        ) from None
    return fit, groups


def _missing_edge_reason(name: str, s: EdgeSamples, min_contrast: float) -> str:
    """The operator's words for a line with fewer than three usable points (``min_contrast``: the least step
    an edge needs, grey levels)."""
    face_step = np.abs(s.step[np.isfinite(s.step)])
    if s.strip_contrast is not None and face_step.size and float(np.median(face_step)) < min_contrast:
        # The strip's shading is read against the step from the background to the hinge face: where the two
        # are as bright, a strip that stands out from both has nothing to be measured against (arris range
        # bench, round seed 8124: a bright 2.6 mm rounding on a face within a grey level of its background,
        # every line's strip fit missing its profiles by hundreds of noise units).
        return (
            f"the {HUMAN[name]} was not found: the hinge face hardly differs from the background behind the "
            f"door (a step of {float(np.median(face_step)):.1f} grey levels; edges need {min_contrast:g}), so "
            "its arris strip could not be read; put a lighter or darker background behind the door, or light "
            "the door's face differently"
        )
    if s.strip_contrast is not None and s.scan.size and not s.valid.any():
        # Every scan line's strip fit failed: the strip's shape was not found anywhere along the edge. On
        # an arris whose wood is as dark as what lies behind the door (arris range bench, dark set) the
        # strip's outer border has no contrast, and the one step the image shows may be either border.
        return (
            f"the {HUMAN[name]} was not found: its arris strip could not be read anywhere along the edge "
            "(an arris about as dark as the background behind the door shows no outer border); light the "
            "door's edges from the side or put a lighter background behind the door, and check that "
            "nothing covers that edge"
        )
    return (
        f"the {HUMAN[name]} was not found (no clean step of the expected polarity); check that the door "
        "lies in the fixture and nothing covers that edge"
    )


@dataclass(frozen=True)
class _Profiles:
    samples: EdgeSamples
    mask: np.ndarray
    lut: np.ndarray | None


def refine(
    plane,
    s8: float,
    region: SearchRegion,
    pose: MetricPose,
    cfg: LocateConfig,
    clock: StageClock,
    response_gamma: float = 1.0,
) -> Refined:
    """The refine stage: sub-pixel edge points and the joint line fit, in passes (module docstring).

    ``response_gamma`` is the camera's (``camera.response_gamma`` in the cell file): grey levels are turned
    back into light before the sub-pixel estimate, which needs them proportional.
    """
    # each pass's arris strip fits, per line (a line's last fit stands where a later pass found none)
    arris_fits: dict[str, tuple[StripFit, float]] = {}
    half = cfg.half_window_max
    blur = float("nan")
    optical_blur = face_slope_blur = float("nan")
    step_fit: dict[str, float] = {}
    ref0: _Profiles | None = None  # the reference arris's first-pass profiles (for the blur)
    widths: list[float] = []  # the first pass's transition widths, bottom end and reference arris (px)
    first_fits: dict[str, tuple[StripFit, float]] = {}  # the first pass's strip fits
    n_pass = 2
    _pass = 0
    recentred = False  # (one more pass where a sloped line's windows missed its edge)
    while _pass < n_pass:
        # The first pass, on every fifth scan line, only centres and sizes the final windows.
        this_pass = _Pass(
            half,
            every=5 if _pass == 0 else 1,
            sharp=_pass > 0 and blur < 0.6,
            optical_blur_px=optical_blur,
            step_fit=step_fit if _pass > 0 else {},
            blur_priors=_blur_priors(arris_fits),
            face_slope_blur_px=face_slope_blur,
        )
        sampled = _sample(plane, s8, region, pose, cfg, this_pass, response_gamma, arris_fits)
        samples, far_beside, far_fit = sampled.samples, sampled.far_beside, sampled.far_fit
        if far_beside and _pass >= 1 and not np.isfinite(optical_blur) and ref0 is not None:
            # The far face came into view after the first pass: measure the blur and look again.
            optical_blur = _within_narrowest(
                _optical_blur(plane, ref0, cfg, blur, arris_fits), widths, region.door
            )
            n_pass = max(n_pass, _pass + 2)
        elif far_beside and _pass == 1:
            # The far face's band width follows from the thickness being measured: one more round.
            n_pass = 3
        clock.lap(f"edges{min(_pass + 1, 2)}")
        fit, points = _fit(
            samples,
            region,
            cfg,
            n_iter=6 if _pass == 0 else 9,
            far_offset_only=far_beside,
            centring=_pass == 0,
        )
        pose = pose_from_fit(fit, region.face_map)
        clock.lap(f"fit{min(_pass + 1, 2)}")
        if _pass >= 1 and not recentred and _plain_lines_lost(sampled):
            recentred, n_pass = True, max(n_pass, _pass + 2)
        if _pass == 0:
            # The final windows sized to the transition widths of the bottom end and the reference arris
            # (beside the far arris a far face or an arris strip can make two steps that look like blur).
            lut = linearizing_lut(plane.dtype, response_gamma)
            widths = _first_pass_widths(plane, samples, fit, region, cfg, half, lut)
            blur, half = _final_window(cfg, widths)
            ref0 = _Profiles(samples["reference"], fit.weights["reference"] > 0, lut)
            first_fits = dict(arris_fits)
            if far_beside:
                # The far arris model needs the optical blur alone: measured on the reference arris.
                optical_blur = _optical_blur(plane, ref0, cfg, blur, arris_fits)
            own_blur = partial(_step_blur_known, optical_blur, plane, ref0, cfg, blur, arris_fits)
            step_fit, face_slope_blur = step_fit_lines(cfg, widths, samples, own_blur)
            optical_blur = _within_narrowest(optical_blur, widths, region.door)
        _pass += 1
    arris_fits = _held_to_first_pass(arris_fits, first_fits)
    found = (sampled.step_fitted, arris_fits, sampled.readers_apart, points)
    later = (None, sampled.face_sloped, (float(widths[0]), float(widths[1])))  # (no direction votes yet)
    return Refined(samples, fit, pose, blur, half, far_beside, far_fit, *found, *later)


def _final_window(cfg: LocateConfig, widths: Sequence[float]) -> tuple[float, int]:
    """The blur the first pass's transition ``widths`` show (px: the wider finite one, else the largest
    window), and the final window's half width sized to it (px): wide enough for the transition, no wider
    (noise)."""
    # np.nanmax of the pair when one is finite, without numpy
    blur = (
        float(max(w for w in widths if not math.isnan(w)))
        if any(math.isfinite(w) for w in widths)
        else float(cfg.half_window_max)
    )
    half = min(max(math.ceil(cfg.window_blur_factor * blur + 1.0), cfg.half_window_min), cfg.half_window_max)
    return blur, half


def _plain_lines_lost(sampled: _Sampled) -> bool:
    """Whether a line read as a plain step (its face sloped or not) kept fewer than
    ``PLAIN_LINES_KEPT_SHARE`` of its points: its windows were centred off its edge. A bright stripe beside
    an arris moves the first pass's area estimates into the face: strong-grain bench, set seed 506, door 36,
    the reference arris's first-pass line 3.5-5 px into the face, and the final pass kept 67 of its 704
    points; `bench_surfaces.py --sets grain_strong --seed 490100` (the set's seed 490107), door 12, a
    stripe along the far arris's top put its first-pass points 3-4.6 px off and the final windows 1.7-5 px
    off; the final pass kept 396 of its 666 points, those near the top 2-3 px off, which tilted the line
    (refused as not straight)."""
    return any(
        sampled.samples[k].scan.size
        and np.count_nonzero(sampled.samples[k].valid) < PLAIN_LINES_KEPT_SHARE * sampled.samples[k].scan.size
        for k in sampled.plain_steps
    )


def _blur_priors(fits: dict[str, tuple[StripFit, float]]) -> dict[str, tuple[float, float]]:
    """Each arris line's prior on its strip's blur (mean, sd px) from the blur the door's other strips
    read in ``fits`` (:func:`doorloc.vision.strip_posterior.strip_blur_priors`)."""
    return strip_blur_priors({k: strip.blur_reading for k, (strip, _) in fits.items()})


def _reading_again(refined: Refined, names: tuple[str, ...]) -> _Pass:
    """The pass that reads the arris lines ``names`` again at the refined pose and windows: the optical blur
    the reference arris's strip read where a far face is beside the far arris, the step fit's lines, the
    strips' blur priors; their doubts not read."""
    optical = float("nan")
    if refined.far_beside and "reference" in refined.arris_fits:
        optical = float(refined.arris_fits["reference"][0].blur_px)
    return _Pass(
        refined.half,
        optical_blur_px=optical,
        step_fit=refined.step_fitted,
        lines=names,
        strip_doubts=False,
        blur_priors=_blur_priors(refined.arris_fits),
    )


def _held_to_first_pass(
    final: dict[str, tuple[StripFit, float]], first: dict[str, tuple[StripFit, float]]
) -> dict[str, tuple[StripFit, float]]:
    """The final pass's strip fits, no surer than the first pass of which border a strip's one step is.

    A strip at the background's level and one at the hinge face's both show one step, a strip's width
    apart (the strip's inner border, or its outer). The first pass's window holds both readings, and
    where its best fit is one and its posterior's mean lies towards the other (by ``READINGS_GAP`` of the
    strip's width or more), or its posterior spreads over both (a best reading of one plain step, its sd
    ``READINGS_SPREAD`` or more), the image did not tell them apart; the final pass centres its narrower window
    on that mean, holds one reading alone and reads it confidently. On the bottom end, whose reading no
    other measurement checks (``READINGS_UNCHECKED``; the side arrises' are held to the recipe's thickness),
    its deficit sigma is then at least the first pass's, with the final reading's distance from the first
    pass's mean. (On every line it cost answers the thickness check already guards: the far arris of a
    rounding in shadow at its silhouette, tests/vision/test_arris_model.py, was refused. An arris
    narrower than the thickness tolerance, misread on one side only, hides within that tolerance: not
    covered.) Measured: a 1.55 mm rounding under ambient light through a 0.4 px blur
    (tests/vision/test_arris_model.py): the first pass fitted the bottom end best at the background's level
    (deficit 1.007) with its mean at 0.054 +- 0.18; the final pass read 0.006 +- 0.000, and the door was
    answered 1.41 mm off in z at a sigma of 0.014 mm; now refused `uncertain` (z 0.27 mm). Its cost on the
    arris bench (seed 7900, nine sets of 16): no answer changed; seed 8100's 32 `focused_dark` doors: one
    right answer refused (a 1.22 mm rounding, z sigma 0.064 -> 0.55 mm). The spread: a 2.51 mm chamfer at
    the background's level under grain, gradients and JPEG (bench_surfaces.py --sets combined --seed 47000,
    door 22): its two readings fitted alike (misfit 1.3 each), the posterior's mean 0.129 +- 0.304 from a best
    reading of 0.021, a gap of 0.11; the final pass read 0.011 +- 0.004 and the door was answered 2.29 mm off
    in z at 64 sigma.
    """
    out = dict(final)
    for k in READINGS_UNCHECKED:
        if k not in final or k not in first:
            continue
        (strip, band_px), s1 = final[k], first[k][0]
        floor = math.hypot(s1.deficit_sigma, strip.deficit - s1.deficit)
        split = abs(s1.deficit - s1.model_deficit) >= READINGS_GAP or (
            shows_one_step(s1.model_deficit) and s1.deficit_sigma >= READINGS_SPREAD
        )
        if split and floor > strip.deficit_sigma:
            out[k] = (replace(strip, deficit_sigma=floor), band_px)
    return out


def arris_response_shifts(
    plane,
    s8: float,
    region: SearchRegion,
    refined: Refined,
    cfg: LocateConfig,
    used_gamma: float,
    camera_gammas: list[float],
    scores: str = "all",
    memo: dict[float, tuple[dict[str, EdgeSamples], list]] | None = None,
) -> StripReadings:
    """How far each arris line's points move, px along its scan lines, were the camera's exponent each of
    ``camera_gammas`` instead of ``used_gamma`` (the one ``refined`` was read with), and how well the
    strips read with each exponent fit (:class:`doorloc.vision.strip_response.StripReadings`: rounded ones
    as matt arcs, chamfered ones in the camera's grey levels; ``scores``: ``"all"``, ``"trials"`` (not at
    ``used_gamma``, whose score the caller has) or ``"none"``).

    The arris strip model (:class:`doorloc.vision.edge_models.ArrisStrip`) reads each line again at the
    final pose and windows, its grey levels turned to light with each exponent: the median over the scan
    lines of the difference to its reading with ``used_gamma``. This is the shift the camera response
    makes on what locate measures there: the strip's fitted shading takes up part of a wrong exponent's
    distortion or adds to it, which a plain step's figure (:func:`doorloc.vision.response.edge_shifts_px`) cannot know.
    A line whose reading fails at an exponent gets NaN there; a line the far-face model reads, no entry.
    ``memo`` (exponent -> the lines' points and what scores the strips read with it: a rounded door's
    arcs, a chamfered door's grey-level misfits), where given, keeps each reading for the door's next call:
    a second call for inner exponents reads ``used_gamma`` again only for the base of its shifts (a rounded
    door's reading: ~0.1 s).

    It costs about half of an arris door's locate (the strip fits, three per line; fixtures/rendered/effects:
    82-109 of 184-195 ms thread CPU per frame, median, one thread). Cheaper readings were
    measured and not taken (seed 7300, round, small and grain sets, 45 lines): the final pass's own
    samples for the ``used_gamma`` reading (a third less) agree on chamfers to 1e-4 px but differ by up
    to 0.59 px on roundings, whose strip fit takes another valley as the window moves with the last fit;
    every 4th scan line (the strip's fit is per line, so 5 % less) moved the roundings' shifts by up to
    0.9 px; one exponent and a symmetric move cannot be had, the two ends' shifts differ up to sixfold.
    """
    # why many parameters: the image and its grey scale, the search region, the refined state and the
    # config that fixed its windows, the exponent it was read with, those to try and whether to score it
    # (beside a far face the far-face model reads the far line, and reports its own doubt); and a memo of
    # the readings, which one door's calls share
    names = tuple(
        k for k in EDGE_NAMES if k in refined.arris_fits and not (k == "far" and refined.far_beside)
    )
    if not names:
        return StripReadings({}, np.full(len(camera_gammas), np.nan), math.nan)
    this_pass = _reading_again(refined, names)
    memo = {} if memo is None else memo
    chamfered = region.door.arris_profile == "chamfer"
    read, strips = [], []
    for g in [used_gamma, *camera_gammas]:
        if g not in memo:
            fits: dict[str, tuple[StripFit, float]] = {}
            points = _sample(plane, s8, region, refined.pose, cfg, this_pass, g, fits).samples
            if chamfered:
                # (a chamfer's strips score in the camera's grey levels; a rounding's as matt arcs)
                memo[g] = (points, [f.grey_misfit for f, _ in fits.values()])
            else:
                arcs = [f.misfit_under_lights for f, _ in fits.values() if f.misfit_under_lights is not None]
                memo[g] = (points, arcs)
        read.append(memo[g][0])
        strips.append(memo[g][1])
    out = {}
    for k in names:
        shifts = np.full(len(camera_gammas), np.nan)
        base = read[0][k]
        for i, other in enumerate(read[1:]):
            d = other[k].along - base.along
            d = d[base.valid & other[k].valid & np.isfinite(d)]
            if d.size >= 5:
                shifts[i] = float(np.median(d))
        out[k] = shifts
    score = grey_score if chamfered else arc_score
    trials = [score(s) if scores != "none" else math.nan for s in strips[1:]]
    used = score(strips[0]) if scores == "all" else math.nan
    return StripReadings(out, np.array(trials), used, "chamfers" if chamfered else "arcs")


def _first_pass_widths(
    plane,
    samples: dict[str, EdgeSamples],
    fit: RectangleFit,
    region: SearchRegion,
    cfg: LocateConfig,
    half: int,
    lut,
) -> list[float]:
    """The transition widths (px, :func:`doorloc.vision.transition.transition_width`) of the bottom end and
    the reference arris on the first pass's points.

    A plain reference arris's is also read on the background's side of its mean transition: the hinge
    face's grain runs along it, and a grain line beside it is no blur (on the surfaces bench's strong grain
    set, seed 2517, a 1.35 px blur read 2.44 px, the windows grew and the step fit was not used: x 0.33 mm
    off). Across the bottom end the grain runs through the edge and averages out, and an arris strip is no
    step on either side.
    """
    # why many parameters: the first pass's image, points, fit and search region, and the config and window that read them
    return [
        transition_width(
            plane,
            samples[k],
            fit.weights[k] > 0,
            half,
            lut,
            quiet_side=(
                -region.layouts[k].door_side(cfg.door_brighter)
                if k == "reference" and not region.door.arris_mm > 0
                else 0
            ),
        )
        for k in ("bottom", "reference")
    ]


def _optical_blur(
    plane,
    ref: _Profiles,
    cfg: LocateConfig,
    transition_px: float,
    arris_fits: dict[str, tuple[StripFit, float]] | None,
    max_lines: int = 160,
) -> float:
    """The optical blur (Gaussian sigma, px) that the far-face model needs, from the reference arris (its
    plain step's blur read on up to ``max_lines`` scan lines).

    On a plain reference arris the step's own blur (:func:`doorloc.vision.step_blur.step_blur`). Where the
    reference arris has a chamfered or rounded strip, its profile is background | strip | face: a step
    blur fit would take the strip's width for blur (3.5 px on the effects fixtures' 1.5 mm chamfer for an
    optical blur of 0.8 px; the far-face fit then lost every scan line and the frame was refused), so
    the blur that the strip's shading fit found with the strip modelled is used instead.
    """
    if arris_fits and "reference" in arris_fits:
        b = float(arris_fits["reference"][0].blur_px)
        if math.isfinite(b) and b > 0:
            return b
    return step_blur(
        plane,
        ref.samples,
        ref.mask,
        cfg.half_window_max,
        cfg.plateau,
        ref.lut,
        blur_px=math.sqrt(max(transition_px * transition_px - 1.0 / 12.0, 0.04)),
        max_lines=max_lines,
    )


def _within_narrowest(optical_px: float, widths: Sequence[float], door: DoorSize) -> float:
    """The optical blur for the far-face model (px): a plain door's reference-arris step blur
    ``optical_px``, or the blur of the narrowest of the first pass's transition ``widths`` (px; the pixel's
    share taken out) where the step blur exceeds it ``OPTICAL_BLUR_NARROW_FACTOR`` times or more.

    The blur is the same on every edge, and the transition widths are read on the reference arris's quiet
    side (:func:`_first_pass_widths`), while the step blur fits the profiles' both sides: wood grain along
    the hinge face widens it. The far-face model holds the blur it is given, and beside a narrow far face
    the blur, the band's level and the arris trade off: a 30.5 mm door under 22 % grain, its lens's blur
    1.03 px, read 2.61 px on its reference arris (its narrowest transition 1.19 px), and its far face's
    9 px band at the background's level was fitted as a 1.6 px band twice as bright as the hinge face: the
    valid door measured 2.14 mm thick at 52 sigma and was refused ``thickness_mismatch``
    (``bench_surfaces.py --sets grain_strong --n 30 --seed 14400``, door 27). An arris strip's own blur
    (the reference arris's strip fit, which models the strip) stands as it is: a strip widens the
    transitions, not its fit's blur."""
    if door.arris_mm > 0 or not math.isfinite(optical_px):
        return optical_px
    narrow = narrowest_blur(widths)
    return narrow if narrow > 0.0 and optical_px >= OPTICAL_BLUR_NARROW_FACTOR * narrow else optical_px


def _step_blur_known(
    known: float,
    plane,
    ref: _Profiles,
    cfg: LocateConfig,
    transition_px: float,
    arris_fits: dict[str, tuple[StripFit, float]],
) -> float:
    """The reference arris's own blur (px): ``known`` where it was read for the far face, else read on
    ``STEP_FIT_CHECK_LINES`` scan lines (:func:`_optical_blur`)."""
    if math.isfinite(known):
        return known
    return _optical_blur(plane, ref, cfg, transition_px, arris_fits, STEP_FIT_CHECK_LINES)
