"""A plain edge's texture doubt: how far the wood grain beside and at an edge may move its points.

:func:`plain_edge_texture` takes what the texture beyond the edge's window suggests
(:func:`doorloc.vision.texture.texture_bias`) and raises it to what the edge shows itself: where a second
reader (the blurred-step fit, tried on a blurred edge or read beside a sharp one as a witness) lies apart from
the area estimator; a reference arris's transition wider than the bottom end's; the structure of the
line's residuals along it; a tilt of at least its halves' biases apart by its own offset doubt. The doubts
stage (:mod:`doorloc.vision.doubts`) gathers it with the others.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.vision.blurred_step import STEP_FIT_MIN_BLUR_PX
from doorloc.vision.edge_models import ReadersApart, step_fit_witness
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.jit import kernel
from doorloc.vision.state import Refined
from doorloc.vision.step_fit_lines import STEP_FIT_PHASE_SWEEP_PX, phase_sweep_px
from doorloc.vision.texture import TextureBias
from doorloc.vision.transition import narrowest_blur

__all__ = [
    "HALVES_APART_OFFSETS",
    "REFERENCE_WIDER_PX",
    "RESIDUAL_BLOCKS",
    "SHARP_WITNESS_TEXTURE_PX",
    "halves_apart_tilt",
    "plain_edge_texture",
    "reference_width_spread_px",
    "residual_structure_tilt",
    "unexplained_spread_px",
]


def plain_edge_texture(
    plane: np.ndarray, r: Refined, k: str, texture: TextureBias, lut: np.ndarray | None
) -> tuple[float, float]:
    """Line ``k``'s texture doubt (offset px, tilt px per px): ``texture`` (beyond its window, read with the
    levels' table ``lut``) raised to what the edge shows itself (:func:`_raised`), with the step fit's
    witness read on ``plane`` where the line takes one (:func:`_sharp_and_swept`)."""
    apart = r.readers_apart.get(k)
    if apart is None and k not in r.arris_fits and _sharp_and_swept(r, k, texture.offset_sigma_px):
        apart = step_fit_witness(plane, r.samples[k], r.half, lut)
    return _raised(r, k, texture.offset_sigma_px, texture.tilt_sigma, apart)


#: a plain edge of a door sharper than the step fit's least blur, whose texture beyond the window moves its
#: area estimate by this much (px, 1 sigma) or more, has the step fit read beside it as a witness
#: (:func:`doorloc.vision.edge_models.step_fit_witness`): its noise alone reads a few thousandths
SHARP_WITNESS_TEXTURE_PX = 0.02


def _sharp_and_swept(r: Refined, k: str, texture_px: float) -> bool:
    """Whether line ``k`` takes the step fit's witness: no step fit read the door's edges, their optical blur
    (the narrowest first-pass transition's) is under the fit's least, the texture beyond its window reaches
    ``SHARP_WITNESS_TEXTURE_PX`` and its pixel phases sweep ``STEP_FIT_PHASE_SWEEP_PX`` (the step fits' own
    rule: on a line at about one phase the witness reads its model's phase bias, 0.09-0.13 px on a square
    door without grain)."""
    if r.step_fitted or r.face_sloped or not texture_px >= SHARP_WITNESS_TEXTURE_PX:
        return False
    if not narrowest_blur(r.transition_widths_px) < STEP_FIT_MIN_BLUR_PX:
        return False
    return phase_sweep_px(r.samples[k]) >= STEP_FIT_PHASE_SWEEP_PX


def _raised(
    r: Refined, k: str, offset_px: float, tilt: float, apart: ReadersApart | None
) -> tuple[float, float]:
    """A plain line's texture doubt (offset px, tilt px per px) from what the texture beyond its window
    suggests (``offset_px``, ``tilt``: :func:`doorloc.vision.texture.texture_bias`), raised to what this
    edge shows itself:

    - where the blurred-step fit was tried, or read beside a sharp edge as a witness (``apart``), how far
      its points lay from the area estimator's (median, and its difference between the edge's halves over
      their distance: :class:`doorloc.vision.edge_models.ReadersApart`). The two
      read the same scan lines and take the grey levels at different distances from the transition, so
      the texture under the window moves a reader at least that much. The texture beyond the window is a
      sample of the grain, not the grain under it: on the surfaces bench's grain set (seed 2511) a dark
      grain line right at the reference arris moved it 0.23 px where the texture beyond said 0.05 px,
      x 0.094 mm off at 5.6 sigma;
    - the tilt that the structure of its residuals over quarters of the line could hide
      (:func:`residual_structure_tilt`): grain wanders along the height (the renderer's by 0.5-2 mm over
      150-400 mm), and the bias it gives the edge with it; the line's own standard error takes its
      residuals as independent (arris lines carry this in their arris doubt);
    - at least the tilt of its two halves' biases lying its offset doubt apart (:func:`halves_apart_tilt`).
    """
    if apart is not None:
        offset_px = _at_least(offset_px, abs(apart.shift_px))
        tilt = _at_least(tilt, abs(apart.tilt))
    if k == "reference":
        offset_px = _at_least(offset_px, reference_width_spread_px(r))
    if k not in r.arris_fits:
        tilt = _at_least(
            tilt,
            residual_structure_tilt(
                r.samples[k], r.fit.residuals[k] / r.pose.scale_mm_per_px, r.fit.weights[k] > 0
            ),
        )
        tilt = _at_least(tilt, halves_apart_tilt(offset_px, r.samples[k]))
    return offset_px, tilt


#: how far apart (in the line's own offset doubt) the texture's bias on a plain line's two halves may lie
#: (:func:`halves_apart_tilt`)
HALVES_APART_OFFSETS = 1.0


def halves_apart_tilt(offset_px: float, samples: EdgeSamples) -> float:
    """The least tilt doubt (px per px) of a plain line whose texture moves it by ``offset_px`` (1 sigma): its
    two halves' biases ``HALVES_APART_OFFSETS`` times that apart, over half the length its points span.

    The texture's own tilt estimates (the texture beyond the window read in two halves, the structure of
    the residuals over quarters of the line) rest on a few samples each, and a grain stripe that wanders
    towards the edge along the line can tilt it more than either saw: through Bouguet's camera model
    (``bench_camera_doors.py --model R --seed 530100``, door_016, grain 3.9 %) the far arris's points moved
    1.1e-4 px per px with the grain (0.077 px over its 698 px) where they allowed 3.6e-5; its offset doubt
    was 0.020 px. NaN (no floor) with fewer than two points."""
    scan = samples.scan[samples.valid]
    if scan.size < 2:
        return math.nan
    span = float(scan.max() - scan.min())
    return 2.0 * HALVES_APART_OFFSETS * offset_px / span if span > 0 else math.nan


#: a plain reference arris whose first-pass transition is wider than the bottom end's by more than this
#: (px) carries texture at its edge that the lens does not make (:func:`reference_width_spread_px`)
REFERENCE_WIDER_PX = 0.6


def reference_width_spread_px(r: Refined) -> float:
    """The reference arris's doubt (px) from a transition wider than the bottom end's (0 where it is not
    wider by more than ``REFERENCE_WIDER_PX``, or either line has an arris strip or a width not read): the
    spread the lens does not make, ``sqrt(reference^2 - bottom^2)`` of the first pass's transition widths.

    The blur is the same on every edge, and the reference arris's width is read on its quiet side
    (:func:`doorloc.vision.refine._first_pass_widths`); a grain line right at it widens it nonetheless, and
    moves the edge that the texture beyond the window does not foresee: a 99.9 mm door under 18 % grain, its
    lens's blur 1.41 px, read 3.06 px across the reference arris and 2.09 across the bottom end, and was
    answered 0.39 mm off in x at 7.2 sigma (``bench_surfaces.py --sets grain_strong --n 40 --seed 9900``,
    door 38; its texture term 0.045 mm). Over 990 plain doors of the surfaces bench's grained sets (seeds
    2511, 5151, 7300, 9900, 9950, 12340) the excess passed 0.6 px on five: that one, two refused already,
    and two answers 2.0 and 0.4 sigma off (0.49 px at the most on the others); the bottom end's own excess
    (up to 0.83 px) moved no answer: across it the grain runs through the edge and averages out. (The arris
    doors' strips carry the same rule between their side arrises: :func:`_side_blur_spreads`.)"""
    if "reference" in r.arris_fits or "bottom" in r.arris_fits:
        return 0.0
    bottom, reference = r.transition_widths_px
    return unexplained_spread_px(reference, bottom, REFERENCE_WIDER_PX)


def unexplained_spread_px(wider: float, narrower: float, apart_px: float) -> float:
    """``sqrt(wider^2 - narrower^2)`` px where ``wider`` exceeds ``narrower`` by more than ``apart_px``, else 0
    (NaN too): the spread one edge reads as blur that the lens, the same on every edge, does not make."""
    return math.sqrt(wider * wider - narrower * narrower) if wider - narrower > apart_px else 0.0


def _at_least(value: float, floor: float) -> float:
    """``value``, or ``floor`` where that is larger or ``value`` is NaN (a NaN ``floor`` changes nothing)."""
    return floor if floor > value or (math.isnan(value) and not math.isnan(floor)) else value


#: contiguous blocks along a line over which its residuals' structure is read (:func:`residual_structure_tilt`)
RESIDUAL_BLOCKS = 4


def residual_structure_tilt(samples: EdgeSamples, residual_px: np.ndarray, inliers: np.ndarray) -> float:
    """Standard error of a line's tilt (px per px) from the structure of its residuals along it.

    The line fit's own standard error takes the residuals as independent; a bias that changes slowly along
    the edge shows instead as residuals whose means over ``RESIDUAL_BLOCKS`` contiguous blocks differ.
    Taken as independent block errors of that scatter, the slope they allow is ``sd(block means) /
    sqrt(sum (s_i - mean s)^2)`` over the blocks' centres ``s_i`` (px). NaN with too few points.
    (Compiled, :func:`_structure_tilt`: it runs on every line of every frame.)
    """
    m = inliers & np.isfinite(residual_px)
    scan, res = samples.scan[m].astype(np.float64), residual_px[m].astype(np.float64)
    if scan.size >= 2 and np.any(scan[1:] < scan[:-1]):  # (the scan lines come in order from the tracks)
        order = np.argsort(scan, kind="stable")
        scan, res = scan[order], res[order]
    return float(_structure_tilt(scan, res, RESIDUAL_BLOCKS))


@kernel(lambda k: k(np.arange(40.0), np.zeros(40), 4))
def _structure_tilt(scan, res, blocks):
    """:func:`residual_structure_tilt` on residuals ``res`` sorted by their scan lines ``scan``: the blocks
    as ``np.array_split``'s (the first ``n % blocks`` one longer); NaN under 8 a block."""
    n = scan.size
    if n < 8 * blocks:
        return np.nan
    means = np.empty(blocks)
    centres = np.empty(blocks)
    q, r = n // blocks, n % blocks
    start = 0
    for b in range(blocks):
        size = q + 1 if b < r else q
        sr = 0.0
        sc = 0.0
        for i in range(start, start + size):
            sr += res[i]
            sc += scan[i]
        means[b] = sr / size
        centres[b] = sc / size
        start += size
    mc = centres.mean()
    mm = means.mean()
    spread = 0.0
    var = 0.0
    for b in range(blocks):
        spread += (centres[b] - mc) ** 2
        var += (means[b] - mm) ** 2
    if not spread > 0:
        return np.nan
    return np.sqrt(var / (blocks - 1)) / np.sqrt(spread)
