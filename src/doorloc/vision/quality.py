"""The quality gate: every reason to refuse an answer, each as a small check with a sentence a person can act on.

A check returns None when it passes, or a :class:`Refusal` (machine code + sentence). The thresholds
live in :class:`doorloc.vision.locate.LocateConfig`; nothing here holds state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.cell import Envelope
from doorloc.vision.jit import kernel, median_in_place, pairwise_sum
from doorloc.vision.sampling import median  # np.median's value, without its generic machinery
from doorloc.vision.side_patches import NOISE_STEP_MAX_DN

__all__ = [
    "Refusal",
    "check_image_size",
    "check_exposure",
    "check_envelope",
    "check_thickness",
    "check_corner_support",
    "check_line",
    "check_strip_read_twice",
    "check_strips_took_their_edge",
    "STRIP_BLUR_OTHERS_PX",
    "STRIP_BLUR_TOOK_EDGE_PX",
    "LineLimits",
    "check_overexposed",
    "check_arris_clipped",
    "check_clipped_flat",
    "side_noise",
    "beyond_two_share",
    "flat_share",
    "SideNoise",
    "CLIP_FLAT_MARGIN",
    "CLIP_TOP_GREY",
    "CLIP_NOISE_MIN_GREY",
    "CLIP_DARK_BEYOND_TWO",
    "check_sharpened",
    "NoiseScaleRatios",
    "noise_scale_ratio",
    "NOISE_BLOCK_PX",
    "NOISE_MIN_LEVELS",
    "line_figures",
    "looks_like_pattern",
]


@dataclass(frozen=True)
class Refusal:
    """Why an answer is refused: ``code`` for programs, ``message`` for people."""

    code: str
    message: str


def check_image_size(size: tuple[int, int], calibrated: tuple[int, int]) -> Refusal | None:
    """The image must have the calibrated camera's size (a resized or cropped image breaks K)."""
    if tuple(size) != tuple(calibrated):
        return Refusal(
            "wrong_image_size",
            f"the image is {size[0]}x{size[1]} px but the camera is calibrated for {calibrated[0]}x{calibrated[1]} px; "
            "send the camera's full-resolution image, uncropped and unscaled, or recalibrate for this size",
        )
    return None


#: a level (0-255 scale) at or above which a pixel counts as saturated white (:func:`check_exposure`)
SATURATED_GREY = 250.0


def check_exposure(
    levels: np.ndarray,
    min_contrast: float,
    max_saturated_fraction: float,
    scale_to_8bit: float = 1.0,
    white_grey: float = SATURATED_GREY,
) -> Refusal | None:
    """Black or saturated image, judged on grey levels sampled over the search region: ``levels`` as stored,
    ``levels * scale_to_8bit`` (float32) on the 0-255 scale the thresholds use, ``white_grey`` the level
    from which a pixel is saturated (lower for a camera that clips below full scale)."""
    if levels.dtype == np.uint8 and levels.size:
        p1, p99, sat = _exposure_from_histogram(levels, scale_to_8bit, white_grey)
    else:
        sample = levels.astype(np.float32) * scale_to_8bit
        p1, p99 = np.percentile(sample, [1, 99])
        sat = float(np.mean(sample >= white_grey))
    if p99 < 25 and p99 - p1 < min_contrast:
        return Refusal(
            "black_image",
            "the image is black (no light or the lens is covered); check the lighting, "
            "the lens cap and the exposure time",
        )
    if sat > max_saturated_fraction:
        return Refusal(
            "saturated_image",
            f"{sat:.0%} of the search region is saturated white; reduce the exposure time or the lighting",
        )
    if p99 - p1 < min_contrast:
        return Refusal(
            "low_contrast",
            f"the search region has almost no contrast ({p99 - p1:.0f} grey levels); "
            "check that a door is in the fixture and that the lighting is on",
        )
    return None


def _exposure_from_histogram(
    levels: np.ndarray, scale_to_8bit: float, white_grey: float = SATURATED_GREY
) -> tuple[float, float, float]:
    """The 1st and 99th percentiles and the saturated fraction (>= ``white_grey``) of 8-bit ``levels`` times
    ``scale_to_8bit``: np.percentile's and np.mean's numbers, from the levels' histogram.

    (np.percentile partitions the sample in its generic machinery: ~0.1 ms of a 5 ms frame. A percentile is
    a linear interpolation between two order statistics, which the histogram gives; the interpolation
    below is numpy's ``_lerp`` with its float32 differences and float64 weights.)"""
    counts = np.bincount(levels.ravel(), minlength=256)
    value = np.arange(256, dtype=np.float32) * scale_to_8bit  # what levels.astype(float32) * scale holds
    rank_end = np.cumsum(counts)  # the sorted sample's index after the last of each level
    n = int(rank_end[-1])
    out = []
    for q in (1 / 100, 99 / 100):
        at = (n - 1) * q
        # (at the top numpy takes the last value twice: its weight then multiplies a zero difference)
        lo, hi, t = (
            (n - 1, n - 1, 0.0) if at >= n - 1 else (math.floor(at), math.floor(at) + 1, at - math.floor(at))
        )
        a, b = (value[int(np.searchsorted(rank_end, k, side="right"))] for k in (lo, hi))
        d = b - a  # float32, as numpy takes it
        out.append(float(b) - float(d) * (1.0 - t) if t >= 0.5 else float(a) + float(d) * t)
    saturated = int(counts[value >= white_grey].sum()) / n
    return out[0], out[1], saturated


def check_overexposed(bright_levels: np.ndarray) -> Refusal | None:
    """The hinge face itself clips at white: edge positions would be biased."""
    if bright_levels.size and median(np.asarray(bright_levels)) >= 249.0:
        return Refusal(
            "overexposed",
            "the hinge face is overexposed (its grey level clips at white), which biases "
            "the edges; reduce the exposure time or the lighting",
        )
    return None


def check_arris_clipped(clipped_share: dict[str, float], limit: float, at: str = "white") -> Refusal | None:
    """An arris strip whose highlight clips at white (or at ``at``, in the sentence): ``clipped_share`` maps
    each strip's edge (its name in the sentences) to the share of its scan lines with clipped pixels beside
    the border (:attr:`doorloc.vision.arris_model.StripFit.clipped_share`). Its shading is cut off where the
    fit reads the border's place, so the edge is biased by more than its doubt says (a 1.25 mm chamfer lit at
    a grazing angle, its strips at 255 on a face of 230: z 0.20 mm off at 6 sigma)."""
    worst = max(clipped_share, key=lambda k: clipped_share[k], default=None)
    if worst is None or not clipped_share[worst] > limit:
        return None
    return Refusal(
        "overexposed",
        f"the arris strip along the {worst} clips at {at} on {100 * clipped_share[worst]:.0f} % of its scan "
        "lines (its highlight is cut off), which biases the edge; reduce the exposure time or the lighting",
    )


#: a bright side counts as clipped only where at least this share more of its patches' pixels sit at one grey
#: level than the dark side's noise, carried through the camera's response, leaves there
#: (:func:`check_clipped_flat`)
CLIP_FLAT_MARGIN = 0.08
#: the least noise (0-255, 1-sigma) the dark side must carry to the bright side's level for a flat bright side
#: to tell a clip (at 0.3 grey a sensor's noise leaves 90 % of a patch at one level)
CLIP_NOISE_MIN_GREY = 0.3
#: the least share of the dark side's pixels off its two commonest levels for its noise to be read
#: (:attr:`SideNoise.beyond_two`; a Gaussian noise of 0.5 grey puts 5-16 % there, its mean between two
#: levels or on one)
CLIP_DARK_BEYOND_TWO = 0.05
#: a clip caps every light in the image: a flat bright side counts as one only within this many grey levels
#: (0-255) of the brightest plateau the door's edges see (:func:`check_clipped_flat`)
CLIP_TOP_GREY = 3.0


@dataclass(frozen=True)
class SideNoise:
    """Flat patches on one side of the door's edges (:func:`side_noise`): ``flat_share`` the median over
    the patches of the share of each one's pixels at its commonest level, ``sigma`` the median of their
    noise (1-sigma) and ``level`` the median of their levels, both on the 0-255 scale, and ``beyond_two``
    the median share of their pixels off their two commonest levels (a noise spread over two levels only
    cannot be measured: a level near a rounding boundary splits between them under any small noise)."""

    flat_share: float
    sigma: float
    level: float
    beyond_two: float


def _level_counts(patch: np.ndarray, s8: float) -> np.ndarray:
    """How many of ``patch``'s pixels sit at each 8-bit level (from its lowest), every other row read (half
    a 48 x 128 patch, 3072 pixels, tells a share to about a percent at half the cost on every frame)."""
    rows = patch[::2] if patch.shape[0] >= 4 else patch
    if rows.dtype == np.uint8 and s8 == 1.0:
        return np.bincount(rows.ravel(), minlength=256)  # (the 8-bit image's own levels: no rounding)
    q = np.rint(np.asarray(rows, np.float64) * s8).astype(np.int64).ravel()
    return np.bincount(q - q.min())


def _top_shares(patch: np.ndarray, s8: float) -> tuple[float, float]:
    """The share of ``patch``'s pixels at its commonest 8-bit level, and the share off its two commonest."""
    counts = np.sort(_level_counts(patch, s8))
    n = float(counts.sum())
    return float(counts[-1]) / n, 1.0 - float(counts[-2:].sum()) / n


def flat_share(patch: np.ndarray, s8: float) -> float:
    """The share of ``patch``'s pixels (raw grey levels, 2-D; ``s8`` their scale to 0-255) at its commonest
    8-bit level (NaN for an empty patch).

    A sensor's noise spreads a lit patch over several levels (0.2-0.3 of its pixels at the commonest on
    OpenCV's board photographs, 0.1-0.8 on rendered doors with 0.5-3 grey of read noise and JPEG); a clip
    stores one level, and JPEG decodes a block of one level to that level (OpenCV's overexposed squares:
    0.86-1.00 of a 7 x 7 box at one level, rendered doors clipped at 240 grey: 1.00)."""
    return _top_shares(patch, s8)[0] if patch.size else float("nan")


def beyond_two_share(patches: list[np.ndarray], s8: float) -> float:
    """The median over ``patches`` of the share of each one's pixels off its two commonest 8-bit levels
    (:attr:`SideNoise.beyond_two`, without the rest of :func:`side_noise`'s work); 0 without patches."""
    shares = [_top_shares(p, s8)[1] for p in patches if p.size]
    return float(np.median(shares)) if shares else 0.0


def side_noise(patches: list[np.ndarray], s8: float) -> SideNoise | None:
    """:class:`SideNoise` of ``patches`` (raw grey levels, 2-D; ``s8`` their scale to 0-255); None without
    patches of at least 2 x 2 pixels. The noise is what a plane through each patch leaves, less the rounding
    to grey levels (Sheppard's correction, a twelfth of a level squared): a smooth ramp's rounding reads as
    0.3 grey otherwise, and a gradient across the patch is light, not noise."""
    shares, sigmas, levels, beyond = [], [], [], []
    for p in patches:
        if p.shape[0] < 2 or p.shape[1] < 2:
            continue
        g = np.asarray(p, np.float64) * s8
        flat, off_two = _top_shares(p, s8)
        shares.append(flat)
        beyond.append(off_two)
        rows, cols = np.mgrid[0 : g.shape[0], 0 : g.shape[1]]
        A = np.stack([np.ones(g.size), rows.ravel(), cols.ravel()], 1)
        coef, *_ = np.linalg.lstsq(A, g.ravel(), rcond=None)
        residual = g.ravel() - A @ coef
        residual = residual[np.abs(residual) <= NOISE_STEP_MAX_DN]  # (a stray edge is not noise)
        var = float(np.var(residual)) - s8 * s8 / 12.0 if residual.size else 0.0
        sigmas.append(math.sqrt(max(var, 0.0)))
        levels.append(float(np.median(g)))
    if not shares:
        return None
    return SideNoise(
        float(np.median(shares)), float(np.median(sigmas)), float(np.median(levels)), float(np.median(beyond))
    )


def check_clipped_flat(
    bright: SideNoise | None,
    dark: SideNoise | None,
    gamma: float,
    limit: float,
    top_grey: float,
    what: str = "the bright side of the door's edges",
) -> Refusal | None:
    """The bright side of the door's edges clipped below the top code: its patches beside the edges flat
    (``bright.flat_share`` at least ``limit``) where the dark side's noise, carried to the bright side's
    level through a power-law response of ``gamma`` (``light = grey ** gamma``: a read noise of the sensor
    shrinks on the grey scale by ``(bright / dark) ** (1 - gamma)``, and shot noise only adds to it), would
    leave at most :data:`CLIP_FLAT_MARGIN` less of them at one level, and at the top of what the door's edges
    see (within :data:`CLIP_TOP_GREY` of ``top_grey``, their brightest plateau: a clip caps every light; a
    smooth surface beside a textured one is flat at its own level). A camera whose sensor or tone curve
    saturates at 240 stores an overexposed face there, under the 249 that :func:`check_overexposed` reads
    as white, and such a face's edges lie towards the dark side (rendered doors clipped at 240 grey:
    0.07-0.28 mm off at 2-13 sigma). A noise-free render, or a camera too quiet for its noise to show on
    the grey scale (a dark side spread over fewer than :data:`CLIP_DARK_BEYOND_TWO` beyond two levels, or
    whose noise reaches the bright side under :data:`CLIP_NOISE_MIN_GREY`), is not refused. ``what``: the
    surface ``bright`` was read on, in the sentence (a flat arris strip is read alike)."""
    if bright is None or dark is None or dark.level < 5.0 or not bright.flat_share >= limit:
        return None
    if not dark.beyond_two >= CLIP_DARK_BEYOND_TWO:
        return None  # the dark side's noise is not resolved by the grey levels
    if not bright.level >= top_grey - CLIP_TOP_GREY:
        return None
    sigma = dark.sigma * (bright.level / dark.level) ** (1.0 - gamma)
    # a noise this small rounds to one level almost everywhere: nothing to tell a clip by
    if not sigma >= CLIP_NOISE_MIN_GREY:
        return None
    # the most pixels a rounded Gaussian noise puts at one level (its mean on that level)
    expected = math.erf(0.5 / (sigma * math.sqrt(2.0)))
    if expected > bright.flat_share - CLIP_FLAT_MARGIN:
        return None
    return Refusal(
        "overexposed",
        f"{what} is clipped at {bright.level:.0f} grey ({100 * bright.flat_share:.0f} % "
        f"of its pixels sit at one level, where the dark side's noise would leave "
        f"{100 * expected:.0f} %), which biases the edges; reduce the exposure time or the lighting",
    )


#: the side (px) of the blocks whose means carry a patch's coarse noise (:func:`noise_scale_ratio`)
NOISE_BLOCK_PX = 4
#: a patch's noise from pixel to pixel must reach this (0-255 scale, 1-sigma) to be read: below it, rounding
#: to grey levels, not the sensor, makes the noise
NOISE_MIN_LEVELS = 0.5
#: blocks the patches of one side need together
NOISE_MIN_BLOCKS = 400


@dataclass(frozen=True)
class NoiseScaleRatios:
    """How strong flat patches' noise is between ``NOISE_BLOCK_PX`` blocks against finer scales
    (:func:`noise_scale_ratio`): ``pixel`` against neighbouring pixels, ``box2`` against neighbouring 2 x 2
    boxes. A sensor's white noise reads 1 on both."""

    pixel: float
    box2: float


def noise_scale_ratio(patches: list[np.ndarray], s8: float) -> NoiseScaleRatios | None:
    """How strong the patches' noise is between ``NOISE_BLOCK_PX`` blocks against between pixels: ``k**2``
    times the variance of the differences of the means of ``k x k`` boxes ``k`` apart over that of
    neighbouring pixels' differences (both axes, pooled over the patches, each weighted by its blocks), and
    the same over ``4`` times that of 2 x 2 boxes' means 2 apart; or None where the patches hold fewer than
    ``NOISE_MIN_BLOCKS`` blocks with noise above ``NOISE_MIN_LEVELS`` (``patches``: raw grey levels, 2-D;
    ``s8``: their scale to 0-255).

    A sensor's noise is white: each pixel's own, and the differences of box means carry ``1/k**2`` of its
    pixels' variance, both ratios 1. Differences leave out the light's slow changes over a patch (a
    gradient, vignetting). What the camera does after the sensor moves the ratios one way or the other:
    demosaicking, texture in the scene, wood grain and coarse JPEG keep less of the fine noise or add coarse
    structure (above 1: the squares of Bouguet's photographs 1.19-5.5, OpenCV's JPEGs 13-18), and
    sharpening (an unsharp mask run on the grey levels) raises the fine noise over the coarse (below 1).
    Read by locate's gate (``gate._noise_scale_ratio``) on rendered doors: ``pixel`` 0.54-0.89 sharpened by
    0.3-1 at 0.8-2 px (29 doors), 0.92-1.06 with white sensor noise alone (46 doors; bench/
    bench_arris_range.py prints it). Fine JPEG (quality 94-98) lowers ``pixel`` too, to 0.84-0.96 on white
    noise of 2-6 grey levels: its quantiser rounds the highest frequencies' coefficients, of about the
    noise's size, to a step larger than most of them, and so to more variance than they had. Those
    frequencies barely reach a 2 x 2 box mean, so ``box2`` stays at 0.97-1.05 on average under such JPEG
    (+-0.03 over the patches of one side of a door), where sharpening takes it to 0.70-0.90
    (:func:`check_sharpened`)."""
    k = NOISE_BLOCK_PX
    vf_min = 4 * NOISE_MIN_LEVELS**2 / (s8 * s8)  # two axes, each difference holding two pixels' noise
    fine = medium = coarse = 0.0
    blocks = 0.0
    for p in patches:
        if p.shape[0] < 3 * k or p.shape[1] < 3 * k:
            continue
        vf, vm, vc = _noise_variances(np.ascontiguousarray(p), k, vf_min)
        if not vf >= vf_min:
            continue
        n = p.shape[0] * p.shape[1] / (k * k)
        fine += n * vf
        medium += n * 4 * vm
        coarse += n * k * k * vc
        blocks += n
    if not (blocks >= NOISE_MIN_BLOCKS and fine > 0 and medium > 0):
        return None
    return NoiseScaleRatios(coarse / fine, coarse / medium)


def _noise_warm_up(k) -> None:
    for dtype in (np.uint8, np.uint16, np.float32):  # the planes' grey levels, and other callers' floats
        k(np.zeros((16, 16), dtype), 4, 1.0)


@kernel(_noise_warm_up)
def _noise_variances(p, k, vf_min):
    """The variances of a patch's neighbouring pixels' differences, of the differences of its 2 x 2 box
    means 2 apart and of its ``k x k`` box means ``k`` apart (boxes at every second row and column), each
    summed over the two axes: one pass for the first over the patch and for the others over its integral
    image (numpy's differences and box filter of six patches cost ~0.6 ms a frame). The others NaN where the
    first is under ``vf_min`` (a patch too quiet to read costs half)."""
    H, W = p.shape
    vf = 0.0
    for di, dj in ((1, 0), (0, 1)):  # down the columns, along the rows
        s = ss = 0.0
        for i in range(H - di):
            for j in range(W - dj):
                d = float(p[i + di, j + dj]) - float(p[i, j])
                s += d
                ss += d * d
        n = (H - di) * (W - dj)
        vf += ss / n - (s / n) ** 2
    if not vf >= vf_min:
        return vf, np.nan, np.nan
    integral = np.zeros((H + 1, W + 1))
    for i in range(H):
        row = 0.0
        for j in range(W):
            row += p[i, j]
            integral[i + 1, j + 1] = integral[i, j + 1] + row
    out = [0.0, 0.0]
    for m, b in enumerate((2, k)):
        bb = float(b * b)
        v = 0.0
        for di, dj in ((b, 0), (0, b)):
            s = ss = 0.0
            n = 0
            for i in range(0, H - b - di + 1, 2):
                for j in range(0, W - b - dj + 1, 2):
                    d = (_box_sum(integral, i + di, j + dj, b) - _box_sum(integral, i, j, b)) / bb
                    s += d
                    ss += d * d
                    n += 1
            v += ss / n - (s / n) ** 2
        out[m] = v
    return vf, out[0], out[1]


@kernel(inline=True)
def _box_sum(integral, i, j, b):
    """The sum of the ``b x b`` box at rows ``i..i+b-1``, columns ``j..j+b-1``, from the integral image."""
    return integral[i + b, j + b] - integral[i, j + b] - integral[i + b, j] + integral[i, j]


#: how far below 1 the 2 x 2 boxes' ratio must read, as a share of ``locate.min_noise_scale_ratio``'s
#: distance below 1, for :func:`check_sharpened` (0.90 for the limit 0.85). An unsharp mask of radius 0.8-2 px
#: takes that ratio 0.5-0.8 of the way the pixel ratio goes (white noise; the bench's ``sharpened`` doors read
#: 0.71-0.89 there), fine JPEG (quality 93-97) keeps it at 0.97-1.05 on average on white noise (+-0.03 on one
#: side's patches) and at 0.91 and up on the surface bench's 80 ``hard`` and ``thin`` doors of quality 95
#: (their pixel ratio down to 0.835)
SHARPENED_BOX2_SHARE = 2.0 / 3.0


def check_sharpened(ratios: NoiseScaleRatios | None, limit: float) -> Refusal | None:
    """The camera sharpens its images: flat patches hold less noise at block scale than at pixel scale
    (:func:`noise_scale_ratio`'s ``pixel`` below ``limit``) and than between 2 x 2 boxes (``box2`` below
    ``1 - SHARPENED_BOX2_SHARE (1 - limit)``; fine JPEG lowers only the first). Sharpening run on the grey
    levels grows every edge's bright side in linear light, which no doubt of locate's covers (rendered
    plain doors up to 0.08 mm off at 7 sigma, rounded ones 0.26 mm at 5 sigma)."""
    box2_limit = 1.0 - SHARPENED_BOX2_SHARE * (1.0 - limit)
    if ratios is None or not (ratios.pixel < limit and ratios.box2 < box2_limit):
        return None
    return Refusal(
        "sharpened",
        f"the camera sharpens its images (flat areas hold {ratios.pixel:.2f} of the coarse noise a sensor "
        f"gives against neighbouring pixels and {ratios.box2:.2f} against 2-pixel boxes, below {limit:g} and "
        f"{box2_limit:.2f}), which moves every edge; switch the camera's sharpening (edge enhancement) off",
    )


def _line_figures_warm_up(k) -> None:
    k(
        np.array([1.0, 0.0, 2.0]),
        np.array([0.1, 0.2, -0.3]),
        np.array([50.0, 60.0, -70.0]),
        np.ones(3, np.float32),
    )
    # (edge samples carry their plateau noise as float32 from the area estimate, float64 from other readers)
    k(np.array([1.0, 0.0, 2.0]), np.array([0.1, 0.2, -0.3]), np.array([50.0, 60.0, -70.0]), np.ones(3))


@kernel(_line_figures_warm_up)
def line_figures(weights, residuals, step, noise):
    """The figures :func:`check_line` judges, over a fitted line's inliers (``weights > 0``), compiled:
    ``(n_inliers, mean square residual, median |step|, median noise)`` in the units given (the residual
    squared; the medians np.median's values, in the arrays' own float type, NaN where one is NaN); without
    inliers ``(0, NaN, 0.0, NaN)``."""
    m = 0
    for i in range(weights.size):
        if weights[i] > 0:
            m += 1
    if m == 0:
        return 0, np.nan, 0.0, np.nan
    sq = np.empty(m)
    steps = np.empty(m, step.dtype)
    noises = np.empty(m, noise.dtype)
    j = 0
    nan_step = nan_noise = False
    for i in range(weights.size):
        if weights[i] > 0:
            sq[j] = residuals[i] * residuals[i]
            steps[j] = abs(step[i])
            noises[j] = noise[i]
            nan_step = nan_step or np.isnan(steps[j])
            nan_noise = nan_noise or np.isnan(noises[j])
            j += 1
    contrast = np.nan if nan_step else median_in_place(steps)
    spread = np.nan if nan_noise else median_in_place(noises)
    return m, pairwise_sum(sq, 0, m) / m, contrast, spread


@dataclass(frozen=True)
class LineLimits:
    """What :func:`check_line` asks of a fitted edge: at least ``min_inliers`` inliers and that fraction of
    its points (``min_inlier_fraction``), an RMS residual of at most ``max_rms_px`` px and a contrast of at
    least ``min_contrast`` grey levels (0-255)."""

    min_inliers: int
    min_inlier_fraction: float
    max_rms_px: float
    min_contrast: float


def check_line(
    human: str,
    n_samples: int,
    n_inliers: int,
    rms_px: float,
    contrast: float,
    limits: LineLimits,
    n_read: int,
) -> Refusal | None:
    """One fitted edge (``human``: its name in the sentences): enough support, straight enough, contrasted
    enough (``rms_px`` px, ``contrast`` grey levels 0-255); ``n_read`` of its ``n_samples`` scan lines gave a
    point (the others named apart: a strip read far off its place leaves them)."""
    min_inliers, min_fraction = limits.min_inliers, limits.min_inlier_fraction
    max_rms_px, min_contrast = limits.max_rms_px, limits.min_contrast
    if n_samples == 0 or n_inliers < min_inliers:
        return Refusal(
            "edge_missing",
            f"the {human} was not found ({n_inliers} usable edge points); check that the "
            "door lies in the fixture and that nothing covers that edge",
        )
    if contrast < min_contrast:
        return Refusal(
            "low_contrast",
            f"the {human} has too little contrast ({contrast:.1f} grey levels, need "
            f"{min_contrast:.0f}); improve the lighting or the background behind the door",
        )
    if n_inliers < min_fraction * n_samples:
        unread = f" ({n_samples - n_read} of them gave no edge point at all)" if n_read < n_samples else ""
        return Refusal(
            "edge_not_straight",
            f"only {n_inliers} of {n_samples} points on the {human} lie on a straight line{unread}; "
            "something covers the edge, the edge is damaged, wood grain beside it is as strong as its step, "
            "or this is not a door",
        )
    if rms_px > max_rms_px:
        return Refusal(
            "edge_not_straight",
            f"the {human} is not straight (RMS residual {rms_px:.2f} px, limit "
            f"{max_rms_px:.2f} px); check the edge for damage, debris or grain beside it as strong as its step",
        )
    return None


#: the outliers of an arris line that lie at its strip's other border are one line: their spread (1.4826
#: MAD, px) is at most this share of the strip's width, and their median lies 0.5-1.5 widths from the line
STRIP_OTHER_BORDER_SPREAD = 0.15


def check_strip_read_twice(
    human: str, residuals_px: np.ndarray, weights: np.ndarray, strip_px: float, max_share: float
) -> Refusal | None:
    """An arris line (``human``) whose points the robust line fit left out lie on a second line parallel to
    it, about the strip's width (``strip_px``, px) away, and make up more than ``max_share`` of its points
    (``residuals_px`` signed distances from the line, px; ``weights`` 0 where left out): the strip was read
    at one border on some scan lines and at its other border on the rest, and the line fit took one reading
    by its count of scan lines, which tells nothing of which reading is right.

    A strip whose shading the model misreads does this: a bright chamfer whose highlight the camera's tone
    curve compressed (a response beyond the cell's power law), read at its inner border wherever it was
    brightest and at its outer border inside a shadow band, had its line placed a strip's width (0.46 mm)
    off at 6.3 sigma on the majority's reading (`bench_camera_doors.py --model` a Bouguet-camera report
    ``--seed 71000``, door 5)."""
    ok = np.isfinite(residuals_px)
    left_out = residuals_px[ok & (weights <= 0)]
    n = int(np.count_nonzero(ok))
    if not strip_px > 0 or n == 0 or left_out.size <= max_share * n or left_out.size < 3:
        return None
    centre = median(left_out)
    spread = 1.4826 * median(np.abs(left_out - centre))
    if spread > STRIP_OTHER_BORDER_SPREAD * strip_px or not 0.5 <= abs(centre) / strip_px <= 1.5:
        return None
    return Refusal(
        "uncertain",
        f"the arris strip along the {human} reads two ways: {left_out.size} of its {n} scan lines place its border "
        f"{abs(centre):.1f} px (a strip's width) from where the others do, and the image does not tell which "
        "is right; the strip's shading is not what the model expects (a highlight the camera's response "
        "compresses, a shadow across it): state the camera's measured response or photometric model in the "
        "cell (doorloc calibrate, doorloc check-model --boards), or light the arris more evenly",
    )


#: an arris strip whose fitted blur is this or less (px; the strip fit's floor is 0.1) where another strip of
#: the door reads ``STRIP_BLUR_OTHERS_PX`` or more has taken the edge's own transition into its free shading
#: (:func:`check_strips_took_their_edge`): one lens blurs a door's edges alike within about a tenth of a
#: pixel (``strip_posterior.BLUR_BETWEEN_EDGES_PX``)
STRIP_BLUR_TOOK_EDGE_PX = 0.15
STRIP_BLUR_OTHERS_PX = 0.4


def check_strips_took_their_edge(blurs: dict[str, float], humans: dict[str, str]) -> dict[str, Refusal]:
    """The arris strips (``blurs``: per line its strip fit's blur, px; ``humans``: the lines' names in the
    sentences) whose free shading took the edge's own transition: a blur read at the fit's floor
    (``STRIP_BLUR_TOOK_EDGE_PX`` or less) where another strip of the door reads ``STRIP_BLUR_OTHERS_PX``
    or more. Per such line its refusal, ``uncertain`` (the far arris's as a thickness that cannot be checked).

    Such a fit draws the blurred step as a ramp of the strip's levels, anywhere across the strip, and
    states its place to a few thousandths of a pixel: through a camera with the sRGB curve in a cell stating
    2.2, a 2.91 mm rounding as dark as the background had its reference arris read so (blur 0.10 px, the
    door's other strips 0.65; deficit 0.438 +- 0.0007 where it is 1, or 0 read the other way), 1.5 mm off,
    and the door, measured 4 mm thin, was refused as the wrong door (``bench_arris_range.py --n 32 --seed
    52100 --sets focused_dark --srgb``, seed 60108)."""
    out = {}
    for k, blur in blurs.items():
        others = max((b for j, b in blurs.items() if j != k), default=0.0)
        if not (blur <= STRIP_BLUR_TOOK_EDGE_PX and others >= STRIP_BLUR_OTHERS_PX):
            continue
        said = (
            f"the arris strip along the {humans[k]} reads a blur of {blur:.2f} px where the door's other strips "
            f"read {others:.2f} px: its fitted shading took the edge's own transition, and where its border "
            "lies cannot be told (a strip about as dark as the background, or a camera whose response the "
            "cell's exponent does not describe, does this); "
        )
        lift = "state the camera's measured response in the cell (doorloc calibrate), or light the arris so "
        lift += "that it stands out from the background"
        out[k] = Refusal(
            "uncertain", ("the door's thickness cannot be checked: " if k == "far" else "") + said + lift
        )
    return out


def check_corner_support(name: str, frac: float, n: int, min_fraction: float) -> Refusal | None:
    """The edges must reach the corner: something over the corner (a clamp) makes the answer doubtful."""
    if n == 0 or frac < min_fraction:
        return Refusal(
            "corner_hidden",
            f"the {name} does not reach the reference corner cleanly (only {frac:.0%} of "
            "the edge points next to the corner fit); something (a clamp, debris) hides the "
            "corner: clear it and take the image again",
        )
    return None


def check_envelope(
    x_mm: float, z_mm: float, yaw_deg: float, env: Envelope, margin_mm: float, margin_deg: float
) -> Refusal | None:
    """The pose must lie inside the placement envelope plus a margin."""
    bad = []
    if abs(x_mm) > env.x_mm + margin_mm:
        bad.append(f"x = {x_mm:+.2f} mm (limit +-{env.x_mm:g} mm)")
    if abs(z_mm) > env.z_mm + margin_mm:
        bad.append(f"z = {z_mm:+.2f} mm (limit +-{env.z_mm:g} mm)")
    if abs(yaw_deg) > env.yaw_deg + margin_deg:
        bad.append(f"yaw = {yaw_deg:+.3f} deg (limit +-{env.yaw_deg:g} deg)")
    if bad:
        return Refusal(
            "outside_envelope",
            "the door lies outside the placement envelope: "
            + ", ".join(bad)
            + "; re-seat the door against the fixture stops",
        )
    return None


def check_thickness(
    measured: float,
    expected: float,
    tolerance: float,
    stated_tolerance: float | None = None,
    sigma: float = 0.0,
) -> Refusal | None:
    """The measured thickness must match the door's (a wrong recipe or a wrong door is caught here).

    ``stated_tolerance`` is the tolerance named in the message (the configured one, when a coarse
    measurement is checked against a wider limit). ``sigma`` is the measurement's 1-sigma, mm: a
    mismatch is claimed only where the difference exceeds the tolerance by more than that (a measurement
    that cannot tell is the caller's ``uncertain``, not a wrong door: a valid door whose chamfer the image
    could not resolve measured 1.67 mm thin with a sigma of 0.8 mm, and "check that the right door is in
    the fixture" sent the operator after the wrong cause).

    >>> check_thickness(48.2, 50.0, 1.0) is not None
    True
    >>> check_thickness(48.2, 50.0, 1.0, sigma=0.9) is None
    True
    """
    if not np.isfinite(measured) or abs(measured - expected) > tolerance + max(sigma, 0.0):
        shown = tolerance if stated_tolerance is None else stated_tolerance
        return Refusal(
            "thickness_mismatch",
            f"the door measures {measured:.2f} mm thick but the recipe says "
            f"{expected:.2f} mm (tolerance {shown:g} mm); check that the right "
            "door is in the fixture and that the recipe is the right one",
        )
    return None


def looks_like_pattern(plane_rows: np.ndarray, threshold: float) -> bool:
    """True when many strong steps of alternating sign cross each row: a checkerboard, not a door.

    ``plane_rows``: (N, L) grey profiles (0-255 scale). A door shows two steps per row (its two arrises).
    """
    if plane_rows.size == 0:
        return False
    d = plane_rows[:, 2:] - plane_rows[:, :-2]
    # A printed pattern is flat between its edges; noise is not.
    if float(np.mean(np.abs(d) < threshold / 4)) < 0.6:
        return False
    strong = np.abs(d) >= threshold
    sign = np.sign(d) * strong
    # Count sign runs: a new run starts where a strong sample's sign differs from the previous strong one.
    counts = []
    for row in sign:
        nz = row[row != 0]
        counts.append(int(np.sum(nz[1:] != nz[:-1])) + (1 if nz.size else 0))
    return float(np.median(counts)) >= 5
