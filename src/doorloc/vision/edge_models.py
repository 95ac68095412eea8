"""Edge models: how one edge of the door is read off the pixels along its scan lines, by kind of edge.

Every model reads a :class:`ScanWindow` (the plane, the scan lines and the window on each, the levels'
table) and returns an :class:`EdgeReading` (the edge points, and what the model fitted on the way). Which
model reads an edge is a lookup by its kind (:func:`edge_kind`, :data:`EDGE_MODELS`):

``plain``
    A step between the door and the background: the area estimator
    (:func:`doorloc.vision.edges.subpixel_edges`).
``step_fit``
    A plain step that the refine stage has the blurred-step fit refine, where texture beside it moves the
    plateaus (:func:`doorloc.vision.blurred_step.refine_step_fit`; kept where texture explains its shift);
    where the texture beside it is strong, the fit with the face's level sloped
    (:func:`doorloc.vision.blurred_step.refine_face_slope_fit`) on every plain long arris.
``banded``
    A step with a band beside it on the door side (an arris strip whose shading is not modelled): the area
    estimator between the band and the background (:func:`doorloc.vision.edges.subpixel_edges_banded`).
``arris_strip``
    A chamfered or rounded arris whose strip the geometry predicts: the strip's shading fitted, the sharp
    corner's line from its outer border (:func:`doorloc.vision.arris_lines.arris_edges`).
``far_face``
    The far arris with the door's far face seen beside it: two blurred steps, hinge face | far face |
    background (:func:`doorloc.vision.far_face.subpixel_edges_far_face`).

A new model is a class with a ``read`` method of :class:`EdgeModel`'s shape, an entry in
:data:`EDGE_MODELS`, and a rule in :func:`edge_kind`; the doubts it knows join the uncertainty budget through
:mod:`doorloc.vision.doubts`. The numba kernels stay inside the estimators.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from doorloc.cell import DoorSize
from doorloc.vision.arris_geometry import ArrisGeometry
from doorloc.vision.arris_lines import StripWindow, arris_edges
from doorloc.vision.arris_model import StripFit
from doorloc.vision.blurred_step import STEP_FIT_MIN_BLUR_PX, refine_face_slope_fit, refine_step_fit
from doorloc.vision.edge_samples import EdgeSamples, ScanWindow
from doorloc.vision.edges import subpixel_edges, subpixel_edges_banded
from doorloc.vision.far_band import FarBand, FarFaceFit
from doorloc.vision.far_face import subpixel_edges_far_face
from doorloc.vision.jit import kernel, median_in_place
from doorloc.vision.region import Track
from doorloc.vision.stated_light import StatedLight
from doorloc.vision.strip_prior import STRIP_RADIANCE, STRIP_RADIANCE_SIGMA
from doorloc.vision.texture import texture_bias

__all__ = [
    "ARRIS_PLATEAU_PX",
    "EDGE_MODELS",
    "EdgeModel",
    "EdgeReading",
    "FACE_SLOPE_LINES",
    "PassSettings",
    "ReadersApart",
    "ScanWindow",
    "edge_kind",
    "step_fit_witness",
]

#: plateau samples of the arris strip's profile fit, px
ARRIS_PLATEAU_PX = 4

#: the step fit replaces the area estimate only where they differ by less than this many of the area
#: estimator's texture sigma (plus STEP_FIT_AGREE_FLOOR_PX): a larger shift is a profile shape that the
#: step model lacks, not texture. That sigma is read on the texture beyond the window and a grain line
#: right at the edge is its tail: on the surfaces bench's grain set (seed 2511) one moved the two readers
#: 3.6 of it apart, the step fit's points 0.05 px off and the area estimator's 0.23 (with 3, that door was
#: answered 0.094 mm off); the disagreement itself goes into the line's texture doubt either way
#: (edge_texture.plain_edge_texture)
STEP_FIT_AGREE_SIGMAS = 5.0
STEP_FIT_AGREE_FLOOR_PX = 0.003

#: a long arris (:data:`FACE_SLOPE_LINES`) whose area estimate the texture beyond its window moves by this
#: much (1 sigma, px: :func:`doorloc.vision.texture.texture_bias`) is read with the face's level sloped.
#: Strong wood grain along the edge puts a flank of a stripe beside it (the surfaces bench's
#: ``grain_strong`` set, seed 7700: over 30 doors the reference arris's points 0.17 px RMS off (their
#: median per door), one door 0.79 px and 0.29 mm in x at 4.1 sigma); a clean or noisy face reads far
#: less, and keeps the flat readers (fewer unknowns per scan line)
FACE_SLOPE_TEXTURE_PX = 0.05
#: the edges read with the face sloped: the long arrises, along which a door's wood grain runs (the hinge
#: face is a stile's edge); across the bottom end each scan line has its own level instead, which the
#: plain step's levels follow (:func:`doorloc.vision.plateau_levels.level_smoothing`). With the bottom end
#: read sloped too, z RMS on ``bench_surfaces.py`` sets ``grain`` (seed 11, 20 doors), ``hard`` (seed 11)
#: and ``grain_strong`` (seed 7700) was 0.0053 / 0.0040 / 0.0048 mm; without, 0.0032 / 0.0025 / 0.0032
FACE_SLOPE_LINES = ("reference", "far")
#: the sloped fit's window, px each side of the edge (at least twice the blur and two pixels): the face
#: is a line over a few pixels of a grain stripe, not over a good part of its period. Per door, the median
#: of the reference and far arrises' points against the truth (``grain_strong`` seeds 7700 and 2611, 30
#: doors each, fitted with the renderer's blur): RMS 0.033-0.055 px (the most 0.20) at 5 px, 0.05-0.13 at
#: 8, 0.09-0.57 at 11; the flat step at 5 px 0.08-0.12 (the most 0.31). Located (``bench_surfaces.py``),
#: 6 px answered better than 5: ``hard`` seed 11 x / z RMS 0.0083 / 0.0040 mm against 0.0129 / 0.0084,
#: ``grain`` seed 2611 z 0.0033 mm against 0.0100 (one door 0.075 mm off at 3.6 sigma)
FACE_SLOPE_HALF_PX = 6
#: how much wider the second sloped reading is, px each side, whose disagreement with the first is the
#: line's ``readers_apart`` (how far the face departs from a line)
FACE_SLOPE_CHECK_PX = 3


@dataclass(frozen=True)
class PassSettings:
    """What one pass of the refine stage tells every model beyond its window.

    ``every``: the pass reads every n-th scan line of a track; ``sharp``: the edges are sharper than the
    windows assume; ``optical_blur_px``: the blur measured on the reference arris (NaN before it is);
    ``slope_smooth``: scan lines for the plain estimator's slope; ``door``: the door's size and arris;
    ``arris``: the strips' geometry per line where the door has an arris; ``step_blur_px``: the lines the
    blurred-step fit refines, and the blur it uses; ``face_slope_blur_px``: the blur from which a long
    arris whose texture is strong is read with its face sloped (NaN: none is; the first pass); ``light``:
    the cell's light (its direction in the cell frame and its doubt) where the cell states it;
    ``strip_doubts``: whether the arris strips' doubts are read (False where strips are read again only for
    their places and misfits: their split check is skipped);
    ``strip_blur_priors``: per arris line, the blur the door's other strips read (mean, sd px) on the pass
    before, a prior on its strip's blur.
    """

    every: int
    sharp: bool
    optical_blur_px: float
    slope_smooth: int
    door: DoorSize
    arris: dict[str, ArrisGeometry] | None
    step_blur_px: dict[str, float]
    light: StatedLight | None = None
    strip_doubts: bool = True
    strip_blur_priors: dict[str, tuple[float, float]] = field(default_factory=dict)
    face_slope_blur_px: float = float("nan")

    @property
    def blur_guess_px(self) -> float:
        """The optical blur, or 1 px where it is not measured yet (the first pass only centres windows)."""
        return self.optical_blur_px if np.isfinite(self.optical_blur_px) else 1.0


@dataclass(frozen=True)
class EdgeReading:
    """What a model read on one edge: its points, and what it fitted on the way.

    ``far_fit``: the far-face model's fit; ``strip``: the arris strip's profile fit and the strip's width,
    px; ``step_blur_px``: the blur with which the blurred-step fit refined the points; ``readers_apart``:
    where the step fit was tried, how far its points lay from the area estimator's (kept or not), and where
    the face was read sloped, how far a reading over a window ``FACE_SLOPE_CHECK_PX`` wider lies from its
    points; ``face_slope_half_px``: the sloped fit's window half width, px, where it read the points.
    """

    samples: EdgeSamples
    far_fit: FarFaceFit | None = None
    strip: tuple[StripFit, float] | None = None
    step_blur_px: float | None = None
    readers_apart: ReadersApart | None = None
    face_slope_half_px: int | None = None


@dataclass(frozen=True)
class ReadersApart:
    """Where the blurred-step fit was tried on a plain edge: how far its points lie from the area
    estimator's. The two read the same scan lines and differ only in where they take the edge's grey
    levels (the step fit right beside the transition, the area estimator at the window's ends), so this is
    what texture near the edge does to a reader, measured on this edge rather than inferred from the
    texture farther out (:func:`doorloc.vision.texture.texture_bias`).

    Attributes
    ----------
    shift_px : float
        Median shift of the step fit's points from the area estimator's, px (across the edge).
    tilt : float
        The difference of that median between the edge's two halves (by scan line) over the distance
        between their mean scan lines, px per px along.
    """

    shift_px: float
    tilt: float


class EdgeModel(Protocol):
    def read(self, window: ScanWindow, name: str, track: Track, settings: PassSettings) -> EdgeReading:
        """The edge ``name`` on the scan lines of ``window`` (its ``track``, read every ``settings.every``)."""
        ...


class PlainArea:
    """A plain step: the area estimator."""

    def read(self, window: ScanWindow, name: str, track: Track, settings: PassSettings) -> EdgeReading:
        w = window
        samples = subpixel_edges(
            *w.lines,
            w.plateau,
            w.scale_to_8bit,
            slope_smooth=settings.slope_smooth,
            level_smooth=w.level_smooth,
            lut=w.lut,
        )
        return EdgeReading(samples)


class StepFit:
    """A plain step refined by the blurred-step fit, where the shift it makes is what texture beside the
    edge explains (:data:`STEP_FIT_AGREE_SIGMAS`); else the area estimate stands. On the long arrises
    (:data:`FACE_SLOPE_LINES`), where the texture beyond the window is strong
    (:data:`FACE_SLOPE_TEXTURE_PX`), the fit with the face's level sloped (:func:`_face_sloped`), whatever
    the line's transition width."""

    def read(self, window: ScanWindow, name: str, track: Track, settings: PassSettings) -> EdgeReading:
        area = PlainArea().read(window, name, track, settings).samples
        blur = settings.step_blur_px.get(name)
        sloped_blur = settings.face_slope_blur_px if name in FACE_SLOPE_LINES else math.nan
        if blur is None and math.isnan(sloped_blur):
            return EdgeReading(area)
        # (a line the flat fit does not refine asks only whether to read it sloped: a quarter of the scan
        # lines and half the shifts tell that, for a quarter of the cost)
        few = {} if blur is not None else {"max_lines": 32, "n_shifts": 6}
        w = window
        tex = texture_bias(w.plane, area, area.valid, w.half, w.plateau, w.lut, **few).offset_sigma_px
        tex = tex if math.isfinite(tex) else 0.0
        if tex >= FACE_SLOPE_TEXTURE_PX and math.isfinite(sloped_blur):
            return _face_sloped(window, area, sloped_blur)
        if blur is None:
            return EdgeReading(area)
        fitted = refine_step_fit(window.plane, area, window.half, blur, window.lut)
        apart = _readers_apart(area, fitted)
        if apart is not None and abs(apart.shift_px) <= STEP_FIT_AGREE_SIGMAS * math.hypot(
            tex, STEP_FIT_AGREE_FLOOR_PX
        ):
            return EdgeReading(fitted, step_blur_px=blur, readers_apart=apart)
        return EdgeReading(area, readers_apart=apart)


def _face_sloped(window: ScanWindow, area: EdgeSamples, blur: float) -> EdgeReading:
    """The edge read with the face's level sloped (:func:`doorloc.vision.blurred_step.refine_face_slope_fit`,
    its blur searched from ``blur`` down) on a window of ``FACE_SLOPE_HALF_PX`` each side (twice the blur and
    two pixels where that is more), and again with that blur on one ``FACE_SLOPE_CHECK_PX`` wider: where the
    face departs from a line within the window the two disagree (``readers_apart``)."""
    h = max(FACE_SLOPE_HALF_PX, math.ceil(2.0 * blur + 2.0))
    w = window
    # (refine_face_slope_fit's half is the window's less one, as refine_step_fit's)
    fitted = refine_face_slope_fit(w.plane, area, h - 1, blur, w.door_side, w.lut)
    if not math.isfinite(fitted.blur_px):  # (no point to read: the area estimate stands)
        return EdgeReading(area)
    wider = refine_face_slope_fit(
        w.plane, area, h - 1 + FACE_SLOPE_CHECK_PX, fitted.blur_px, w.door_side, w.lut, search_blur=False
    )
    return EdgeReading(
        fitted.samples,
        step_blur_px=fitted.blur_px,
        readers_apart=_readers_apart(fitted.samples, wider.samples),
        face_slope_half_px=h,
    )


def _readers_apart(area: EdgeSamples, fitted: EdgeSamples) -> ReadersApart | None:
    """How far the step fit's points lie from the area estimator's (None below 16 points)."""
    d = fitted.along - area.along
    ok = np.isfinite(d)
    n = int(np.count_nonzero(ok))
    if n < 16:
        return None
    d, scan = d[ok], area.scan[ok]
    if np.any(scan[1:] < scan[:-1]):  # (the scan lines come in order from the tracks)
        order = np.argsort(scan, kind="stable")
        d, scan = d[order], scan[order]
    shift, tilt = _apart_and_tilt(d, scan.astype(np.float64))
    return ReadersApart(float(shift), float(tilt))


def step_fit_witness(
    plane: np.ndarray, samples: EdgeSamples, half: int, lut: np.ndarray | None
) -> ReadersApart | None:
    """The blurred-step fit read beside a plain edge that no step fit refined (its door's edges sharper than
    the fit's least blur, ``STEP_FIT_MIN_BLUR_PX``), at that blur, kept only as a witness: how far its
    points lie from the area estimator's ``samples`` (:class:`ReadersApart`; None below 16 points).

    On a sharp edge the area estimator takes the face's level a few pixels out and the step fit right
    beside the transition, as on a blurred one: grain at the edge moves the two apart. A strongly grained
    door through a sharp lens (``bench_surfaces.py --sets hard --n 40 --seed 15100``, door 31: blur 0.03
    px, 9 % grain) had its reference arris 0.19 px off and its far arris tilted 0.55 px over its length where the
    texture beyond the windows said 0.04 px and a third of that tilt, and was answered 0.092 mm off in x at
    5.5 sigma; the witness read the reference 0.165 px apart and the far arris's tilt at 4.5e-4 (of 7.8e-4),
    and on the door without grain 0.012 px. Its shape follows the pixel's phase (the step is sharper than
    the fit's blur), which averages out only on a line that sweeps many phases: the caller asks that."""
    return _readers_apart(samples, refine_step_fit(plane, samples, half, STEP_FIT_MIN_BLUR_PX, lut))


@kernel(lambda k: k(np.zeros(20), np.arange(20.0)))
def _apart_and_tilt(d, scan):
    """:func:`_readers_apart`'s figures, compiled: the median of ``d`` (sorted by ``scan``), and the
    difference of the medians of its two halves (the first ``ceil(n / 2)`` and the rest, as
    ``np.array_split``) over the distance between their mean scan lines (0 without one)."""
    n = d.size
    k = n - n // 2
    shift = median_in_place(d.copy())
    lo = median_in_place(d[:k].copy())
    hi = median_in_place(d[k:].copy())
    lever = scan[k:].mean() - scan[:k].mean()
    return shift, (hi - lo) / lever if lever > 0 else 0.0


class Banded:
    """A step with a band beside it on the door side: the area estimator between band and background."""

    def read(self, window: ScanWindow, name: str, track: Track, settings: PassSettings) -> EdgeReading:
        w = window
        assert track.band_px is not None
        samples, _ = subpixel_edges_banded(
            w, track.band_px[:: settings.every], band_slope=track.band_slope, sharp=settings.sharp
        )
        return EdgeReading(samples)


class FarFace:
    """Hinge face | far face (a band of any width and brightness) | background: the profile's shape, two
    blurred steps with the band's width from the geometry. The blur comes from the plain reference arris
    (beside a narrow band, blur, band level and width trade off); only the first pass, which just centres
    the windows, guesses it."""

    def read(self, window: ScanWindow, name: str, track: Track, settings: PassSettings) -> EdgeReading:
        w, every = window, settings.every
        assert track.band_px is not None
        band = FarBand(
            track.band_px[::every],
            track.band_slope,
            strip_px=track.strip_px[::every] if track.strip_px is not None else None,
            strip_radiance=(STRIP_RADIANCE, STRIP_RADIANCE_SIGMA),
            strip_shaded=settings.door.arris_profile == "round",
        )
        samples, far_fit = subpixel_edges_far_face(w, band, blur_px=settings.blur_guess_px)
        return EdgeReading(samples, far_fit=far_fit)


class ArrisStrip:
    """An arris strip on the door side of the outline: its outer border from the strip's fitted shading,
    then moved to the sharp corner's line by the geometry.

    The strip's profile fit takes 4-px plateaus (:data:`ARRIS_PLATEAU_PX`: the face beside the strip pins
    its brightness, most of all on narrow strips); each line's levels for its area estimate the plain
    step's, right beside the window: taken farther out they pick up texture along the edge (the effects
    fixtures' grain: their yaw was up to 0.022 deg off).
    """

    def read(self, window: ScanWindow, name: str, track: Track, settings: PassSettings) -> EdgeReading:
        w, every = window, settings.every
        assert track.band_px is not None and track.outline_shift_px is not None and settings.arris is not None
        band, geometry = track.band_px[::every], settings.arris[name]

        def read_at(lines: ScanWindow) -> tuple[EdgeSamples, StripFit | None]:
            return arris_edges(
                StripWindow(
                    replace(lines, plateau=max(lines.plateau, ARRIS_PLATEAU_PX)),
                    blur0=settings.blur_guess_px,
                    search=every > 1,
                    level_px=lines.plateau,
                    # (the far arris's strip can take another level in the first pass than in the final one,
                    # which its window was placed for: there the area estimate; the line fit in both passes
                    # lost every far point on 2 of 48 arris bench frames)
                    line_fit=name != "far" or every == 1,
                    light=settings.light,
                    split_check=settings.strip_doubts,
                    blur_prior=settings.strip_blur_priors.get(name),
                ),
                band,
                geometry,
            )

        samples, strip = read_at(w)
        if every == 1 and strip is not None and _border_outside_windows(samples, strip, w.half):
            # The strip's fit, over all its lines, puts the outer border beyond the lines' windows (or near
            # their end: STRIP_BORDER_OUTSIDE_SHARE) from where the first pass put it (a first pass led astray
            # by a strip much brighter than the face), and most lines lose their point: read again with the
            # windows centred where the fit puts it, kept where more lines give a point
            # (bench_camera_doors.py --model R --n 32 --seed 72100, door_020: a 2 mm chamfer at 224 grey
            # beside a face of 150-170, its far strip's border 4.2 px beyond the prediction, 18 of 654 lines
            # read; refused edge_missing; read again 654 of 654, answered 0.037 mm off at 0.6 sigma).
            again, strip_again = read_at(replace(w, centre=w.centre + w.door_side * strip.offset_px))
            if strip_again is not None and int(again.valid.sum()) > int(samples.valid.sum()):
                samples, strip = again, strip_again
        samples = replace(samples, along=samples.along + track.outline_shift_px[::every])
        return EdgeReading(samples, strip=(strip, float(np.median(band))) if strip is not None else None)


#: the share of a strip's scan lines under which, with its fitted border beyond their windows, the strip is
#: read again centred there (:meth:`ArrisStrip.read`)
STRIP_LINES_READ_SHARE = 0.5
#: the fraction of the windows' half width beyond which a strip's fitted border counts as outside them: a
#: border near the windows' end loses most lines' points as one beyond it does (door_020 of
#: ``bench_camera_doors.py --model R --n 32 --seed 72100``, its cell stating only the camera's power law: the
#: border 3.95 px out in windows of half width 4, 73 of 654 lines read; refused ``edge_missing``, read again
#: 654 of 654 and answered 0.051 mm off at 0.70 sigma)
STRIP_BORDER_OUTSIDE_SHARE = 0.5


def _border_outside_windows(samples: EdgeSamples, strip: StripFit, half: int) -> bool:
    """Whether a strip read on its final pass lost most of its lines' points (under
    ``STRIP_LINES_READ_SHARE`` of them) with its fitted outer border more than ``STRIP_BORDER_OUTSIDE_SHARE``
    of the windows' ``half`` width (px) from where they were centred."""
    outside = abs(strip.offset_px) > STRIP_BORDER_OUTSIDE_SHARE * half
    return outside and float(np.mean(samples.valid)) < STRIP_LINES_READ_SHARE


#: the model that reads each kind of edge (:func:`edge_kind`)
EDGE_MODELS: dict[str, EdgeModel] = {
    "plain": PlainArea(),
    "step_fit": StepFit(),
    "banded": Banded(),
    "arris_strip": ArrisStrip(),
    "far_face": FarFace(),
}


def edge_kind(name: str, track: Track, settings: PassSettings) -> str:
    """The kind of the edge ``name`` on this pass: which of :data:`EDGE_MODELS` reads it."""
    if track.band_px is None or not track.band_px.size:
        sloped = name in FACE_SLOPE_LINES and math.isfinite(settings.face_slope_blur_px)
        stepped = name in settings.step_blur_px or sloped
        return "step_fit" if stepped else "plain"
    if track.beside_far_face:
        return "far_face"
    if settings.arris is not None and name in settings.arris and track.outline_shift_px is not None:
        return "arris_strip"
    return "banded"
