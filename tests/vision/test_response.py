"""The camera-response measurement on plain edges (vision/response.py), on synthetic steps made here without
the renderer: a Gaussian-blurred, pixel-integrated step recorded through a power-law response."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter
from scipy.special import ndtr

from doorloc.vision.edges import subpixel_edges
from doorloc.vision.response import (
    RESPONSE_ABSORB_SIGMAS,
    LineResponse,
    ResponseFit,
    combine_responses,
    edge_shift_px,
    fit_line_response,
)
from doorloc.vision.response_asymmetry import Transitions
from doorloc.vision.response_check import RESPONSE_OVERSHOOT_MAX
from doorloc.vision.response_overshoot import line_overshoot
from doorloc.vision.response_plateaus import RESPONSE_LEVEL_ROWS, plateau_level_rows
from doorloc.vision.sampling import linearizing_lut

N_COLS, N_ROWS, TILT = 400, 100, 0.031  # a near-horizontal edge: profiles run along the columns


def _step_image(
    camera_gamma: float,
    blur: float,
    lo: float,
    hi: float,
    noise: float,
    seed: int,
    tilt: float = TILT,
    row: float = 50.3,
    halo: tuple[float, float] = (0.0, 1.0),
    stripes: tuple[float, float] = (0.0, 1.0),
    sharpen: tuple[float, float] = (0.0, 1.0),
) -> np.ndarray:
    """8-bit image of a blurred step (light ``lo`` above the edge, ``hi`` below), integrated over each pixel
    on an 8x finer grid, recorded as ``light ** (1 / camera_gamma)``; ``halo``: the share of the light a
    wider Gaussian of the given sigma (px) spreads, the rest ``blur``'s; ``stripes``: grain across the edge,
    the bright side's light changed by that share, sinusoidally with the given period (px) along the edge
    (each column, one profile, its own bright level); ``sharpen``: an unsharp mask of that amount and radius
    (px) run on the recorded grey levels, as a camera that sharpens its images runs one."""
    f = 8
    sub = (np.arange(N_ROWS * f) + 0.5) / f - 0.5  # sub-pixel row centres
    u = np.arange(N_COLS)
    edge = row + tilt * u  # row of the edge in each column
    x = sub[:, None] - edge[None, :]
    hi = hi * (1.0 + stripes[0] * np.sin(2 * np.pi * u / stripes[1]))[None, :]
    light = lo + (hi - lo) * ((1 - halo[0]) * ndtr(x / blur) + halo[0] * ndtr(x / halo[1]))
    light = light.reshape(N_ROWS, f, N_COLS).mean(axis=1)
    raw = 255.0 * light ** (1.0 / camera_gamma)
    if sharpen[0]:
        raw += sharpen[0] * (raw - gaussian_filter(raw, sharpen[1], mode="nearest"))
    raw += np.random.default_rng(seed).normal(0.0, noise, raw.shape)
    return np.clip(np.round(raw), 0, 255).astype(np.uint8)


def _samples(img: np.ndarray, used_gamma: float, half: int, tilt: float = TILT, row: float = 50.3):
    u = np.arange(20, N_COLS - 20)
    return subpixel_edges(img, "col", u, row + tilt * u, half, lut=linearizing_lut(img.dtype, used_gamma))


@pytest.mark.parametrize(
    ("camera_gamma", "used_gamma", "blur"),
    [(1.0, 1.0, 1.0), (2.2, 1.0, 1.5), (1.0, 2.2, 0.8), (1.6, 2.4, 1.2), (2.4, 1.3, 1.8)],
)
def test_the_response_is_measured_from_the_step_shape(camera_gamma, used_gamma, blur):
    img = _step_image(camera_gamma, blur, 0.12, 0.8, 0.7, seed=3)
    s = _samples(img, used_gamma, half=int(math.ceil(2 * blur + 1)))
    lr = fit_line_response(img, s, s.valid, int(math.ceil(2 * blur + 1)), used_gamma, blur)
    assert lr is not None
    # within 3 standard errors, and the standard error small enough to tell gamma 1.0 from 2.2
    assert abs(lr.gamma - camera_gamma) <= 3 * lr.sigma + 0.02, lr
    assert lr.sigma < 0.25
    assert lr.lo == pytest.approx(round(255 * 0.12 ** (1 / camera_gamma)) / 255, abs=0.02)


def _read_in_a_right_cell(img: np.ndarray, camera_gamma: float, blur: float) -> LineResponse:
    """The edge of ``img`` read with the camera's own exponent in use: within 3 of its sigmas of it."""
    half = int(math.ceil(2 * blur + 1))
    s = _samples(img, camera_gamma, half=half)
    lr = fit_line_response(img, s, s.valid, half, camera_gamma, blur)
    assert lr is not None
    assert abs(lr.gamma - camera_gamma) <= 3 * lr.sigma + 0.02, lr
    return lr


@pytest.mark.parametrize("camera_gamma", [1.2, 2.2])
def test_a_lens_halo_is_no_response(camera_gamma):
    # A quarter of the light spread 3.5x wider than the core reaches beyond the profiles' plateaus and slopes
    # both alike in light: an even spread, whose transition is symmetric at the camera's exponent. Taken
    # out as shading (each plateau's slope over its level), it had read a camera of 1.2 as 2.1 +- 0.07.
    blur = 1.6
    img = _step_image(camera_gamma, blur, 0.12, 0.8, 0.9, seed=5, halo=(0.27, 5.6))
    assert _read_in_a_right_cell(img, camera_gamma, blur).sigma < 0.25


@pytest.mark.parametrize("camera_gamma", [1.0, 2.2])
def test_grain_across_the_edge_is_no_response(camera_gamma):
    # Stripes along the profiles (grain across a door's bottom end) give each profile its own bright
    # plateau. Averaged over 8 profiles each side, the plateaus missed each profile's own by the grain's
    # change over them, and that miss, raised to each trial exponent, pulled the least asymmetry: a 2.2
    # camera read 0.98 +- 0.11 here, a linear one 0.45 +- 0.05 (and a door's bottom end 0.76 +- 0.08,
    # taking the cell's right exponent's place); the plateaus are now averaged over fewer neighbours
    # where they differ.
    blur = 1.5
    img = _step_image(camera_gamma, blur, 0.12, 0.7, 0.7, seed=7, stripes=(0.09, 24.0))
    _read_in_a_right_cell(img, camera_gamma, blur)


@pytest.mark.parametrize(
    ("camera_gamma", "blur", "mask_seen"), [(1.0, 0.9, True), (1.85, 1.0, True), (2.2, 1.6, False)]
)
def test_a_sharpened_transition_overshoots_both_plateaus_and_a_blurred_step_neither(
    camera_gamma, blur, mask_seen
):
    # A camera that sharpens its grey levels makes a transition that some exponent no camera has makes
    # symmetric (here a 1.85 camera read 1.14-1.2; on a rendered door 1.12 +- 0.02): its overshoot beyond
    # both plateaus says the reading is no camera's. A blurred step overshoots neither, through a lens halo
    # or under grain across the edge either. (Under a blur wider than the mask's radius, 1.6 px here, the
    # overshoot stays within the plateaus' windows and is not seen: a 2.2 camera then read 1.5-1.7.)
    half = int(math.ceil(2 * blur + 1))
    plain = ({}, {"halo": (0.27, 3.5 * blur)}, {"stripes": (0.09, 24.0)})
    masks = ({"sharpen": (0.36, 2.0)}, {"sharpen": (0.6, 1.4)}) if mask_seen else ()
    for effect in (*plain, *masks):
        img = _step_image(camera_gamma, blur, 0.05, 0.85, 0.7, seed=11, **effect)
        s = _samples(img, camera_gamma, half=half)
        lr = fit_line_response(img, s, s.valid, half, camera_gamma, blur)
        assert lr is not None, effect
        overshoot = line_overshoot(img, s, s.valid, half, lr.gamma, blur)
        if "sharpen" in effect:
            assert overshoot >= RESPONSE_OVERSHOOT_MAX, (effect, lr, overshoot)
        else:
            assert overshoot < 0.25 * RESPONSE_OVERSHOOT_MAX, (effect, lr, overshoot)


def test_plateaus_are_averaged_over_8_profiles_unless_they_differ_from_profile_to_profile():
    rng = np.random.default_rng(2)
    u = np.arange(300)
    steps = np.concatenate([np.full((300, 6), 0.2), np.full((300, 6), 0.8)], axis=1)
    noisy = steps + rng.normal(0.0, 0.004, steps.shape)
    assert plateau_level_rows(noisy) == RESPONSE_LEVEL_ROWS
    # a few profiles' plateaus hit by something else (a distractor crossing the window) are no grain:
    # averaging over their neighbours dilutes them (the median of the misses is unmoved)
    hit = noisy.copy()
    hit[100:106, -3:] -= 0.3
    assert plateau_level_rows(hit) == RESPONSE_LEVEL_ROWS
    grain = noisy.copy()
    grain[:, 6:] *= (1.0 + 0.05 * np.sin(2 * np.pi * u / 20.0))[:, None]
    assert plateau_level_rows(grain) < RESPONSE_LEVEL_ROWS


@pytest.mark.parametrize("row", [50.0, 50.15, 50.3, 50.5, 50.8])
@pytest.mark.parametrize(
    ("camera_gamma", "used_gamma", "blur"), [(2.2, 1.0, 1.4), (1.0, 1.0, 1.1), (1.0, 2.2, 1.8)]
)
def test_an_edge_at_one_pixel_phase_is_read_between_its_pixels(row, camera_gamma, used_gamma, blur):
    """An edge along a pixel row (a door square to the camera): every profile at one phase, each phase of
    the pixel tried. The exponent is read by interpolation, flagged as such, within 2.5 of its sigma of the
    camera's, and that sigma (with its floor for the spline's error) tells a linear camera from a 2.2 one
    by more than 2 of it (one edge alone never replaces the cell's exponent: two together, 4 joint sigmas)."""
    half = int(math.ceil(2 * blur + 1))
    img = _step_image(camera_gamma, blur, 0.12, 0.8, 0.7, seed=5, tilt=0.0, row=row)
    s = _samples(img, used_gamma, half, tilt=0.0, row=row)
    lr = fit_line_response(img, s, s.valid, half, used_gamma, blur)
    assert lr is not None and lr.one_phase
    assert abs(lr.gamma - camera_gamma) <= 2.5 * lr.sigma, lr
    other = 1.0 if camera_gamma > 1.5 else 2.2
    assert abs(lr.gamma - other) > 2.0 * lr.sigma, lr
    # a transition sharper than the spline can follow is not read at all
    sharp = _step_image(camera_gamma, 0.6, 0.12, 0.8, 0.7, seed=5, tilt=0.0, row=row)
    s = _samples(sharp, used_gamma, 3, tilt=0.0, row=row)
    assert fit_line_response(sharp, s, s.valid, 3, used_gamma, 0.6) is None


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_an_edge_nearly_along_a_row_is_at_one_phase_whatever_its_points_noise(seed):
    """A faint edge (light 0.24 to 0.40) 0.02 deg off a pixel row, one grey level of noise: each point's
    own noise scatters a few of them into every quarter of the pixel, but the edge itself keeps one
    phase. Read as one (interpolation, its floor in the sigma), the linear camera stays within
    ``RESPONSE_ABSORB_SIGMAS`` of its sigma of 1.0 (the departure at which a reading replaces the cell's
    exponent; 0.47 +- 0.18 the farthest of these four); counted point by point, such an edge was read as
    at many phases, 1.64 +- 0.06 and 1.91 +- 0.12 here, 2.2-2.3 +- 0.13 on a door, where it replaced a
    right cell's exponent."""
    tilt, blur = 0.0003, 1.1
    half = int(math.ceil(2 * blur + 1))
    img = _step_image(1.0, blur, 0.24, 0.40, 1.0, seed=seed, tilt=tilt)
    s = _samples(img, 1.0, half, tilt=tilt)
    lr = fit_line_response(img, s, s.valid, half, 1.0, blur)
    assert lr is not None and lr.one_phase, lr
    assert abs(lr.gamma - 1.0) <= RESPONSE_ABSORB_SIGMAS * lr.sigma, lr


def test_edge_shift_follows_the_step_model():
    # the exponents agree: no shift
    assert abs(edge_shift_px(0.2, 0.9, 2.2, 2.2, 1.2, 5)) < 1e-3
    # a gamma-2.2 camera read as linear lifts the dark side's tail: the area estimate moves towards the dark side
    s = edge_shift_px(0.2, 0.9, 2.2, 1.0, 1.2, 5)
    assert s < -0.1
    # ... by more for more blur, and by nothing for a step without blur wider than the pixel
    assert edge_shift_px(0.2, 0.9, 2.2, 1.0, 1.8, 6) < s < edge_shift_px(0.2, 0.9, 2.2, 1.0, 0.3, 5) < 0


@pytest.mark.parametrize(("camera_gamma", "used_gamma"), [(2.2, 1.0), (1.0, 2.2)])
def test_the_shift_predicts_the_area_estimators_error(camera_gamma, used_gamma):
    """On the synthetic step the area estimator's mean error is what the step model says (20 %)."""
    blur, half = 1.4, 5
    img = _step_image(camera_gamma, blur, 0.15, 0.85, 0.0, seed=1)
    s = _samples(img, used_gamma, half)
    err = float(np.mean(s.along[s.valid] - (50.3 + TILT * s.scan[s.valid])))
    lo, hi = 255 * 0.15 ** (1 / camera_gamma), 255 * 0.85 ** (1 / camera_gamma)
    pred = edge_shift_px(round(lo) / 255, round(hi) / 255, camera_gamma, used_gamma, blur, half)
    assert abs(err) > 0.05
    assert err == pytest.approx(pred, rel=0.2)


def test_lines_that_disagree_do_not_make_a_confident_response():

    a = LineResponse(2.0, 0.05, 0.1, 0.8, 0.0)
    b = LineResponse(1.4, 0.05, 0.1, 0.8, 0.0)
    fit = combine_responses({"bottom": a, "reference": b}, 1.0)
    assert fit is not None and fit.gamma == pytest.approx(1.7)
    assert fit.sigma > 0.2  # the Birge ratio widens it to the lines' scatter
    agree = combine_responses({"bottom": a, "reference": LineResponse(2.0, 0.05, 0.1, 0.8, 0.0)}, 1.0)
    assert agree is not None and agree.sigma == pytest.approx(0.05 / math.sqrt(2)) and agree.absorb


def test_an_ambiguous_reading_is_not_absorbed_and_a_measured_claim_picks_between_its_readings():

    # both edges read 2.25, and 1.38 about as symmetric (an undithered 8-bit 1.34 camera)
    a = LineResponse(2.25, 0.05, 0.2, 0.9, 0.0, alternatives=(1.38,))
    b = LineResponse(2.24, 0.05, 0.2, 0.9, 0.0, alternatives=(1.36,))
    fit = combine_responses({"bottom": a, "reference": b}, 1.34)
    assert fit is not None and fit.alternatives == (1.36, 1.38) and not fit.absorb
    assert fit.gamma == pytest.approx(2.245)
    # without the second readings the same edges would replace the cell's exponent
    plain = {
        "bottom": LineResponse(2.25, 0.05, 0.2, 0.9, 0.0),
        "reference": LineResponse(2.24, 0.05, 0.2, 0.9, 0.0),
    }
    assert combine_responses(plain, 1.34).absorb  # type: ignore[union-attr]
    # one edge that reads one exponent only decides
    assert combine_responses({"bottom": a, "reference": plain["reference"]}, 1.34).alternatives == ()  # type: ignore[union-attr]
    # a measured cell exponent tells the readings apart: the nearest is the image's
    held = combine_responses({"bottom": a, "reference": b}, 1.34, claimed_sigma=0.05)
    assert held is not None and held.gamma == pytest.approx(1.36) and 2.245 in held.alternatives


def test_an_alternative_one_line_rules_out_is_not_the_images():
    """A plain grained door of a linear camera under a 1.8 px blur (``bench_surfaces.py --sets grain --n 30
    --seed 14300``, door 2): its bottom end read 1.12 +- 0.13 with 1.90 and 2.37 about as symmetric, its
    reference arris 0.95 +- 0.12 with 1.30. Every line admitted others, and the image's alternatives were
    their union: the doubt of a 1.9-2.4 camera refused the valid door (x 0.13 mm of response doubt). One
    camera makes both edges: an exponent that a line neither reads nor admits as its alternative (within
    three of its sigmas) is no camera's; 1.30, which both admit, stays."""
    bottom = LineResponse(1.121, 0.1257, 0.3, 0.8, 0.0, alternatives=(1.8951, 2.373))
    reference = LineResponse(0.9475, 0.1163, 0.3, 0.8, 0.0, alternatives=(1.301,))
    fit = combine_responses({"bottom": bottom, "reference": reference}, 1.0)
    assert fit is not None and fit.alternatives == (1.301,)
    # where both lines admit the same second reading, it stays (both near 2.6 with the camera's 1.1 second)
    a = LineResponse(2.62, 0.02, 0.3, 0.8, 0.0, alternatives=(1.10,))
    b = LineResponse(2.60, 0.03, 0.3, 0.8, 0.0, alternatives=(1.12,))
    both = combine_responses({"bottom": a, "reference": b}, 2.2)
    assert both is not None and both.alternatives == (1.1, 1.12)


def test_an_exponent_beyond_the_cells_claim_is_doubted_only_to_the_claims_end():
    """Exponents the edges admit about as well, beyond what the cell claims (its exponent within
    ``response_unmeasured_factor``, where nobody measured it), count as the claim's end: the camera may lie
    anywhere up to it, but a camera the cell's own claim rules out is not why an image that reads a response
    should doubt it more than an image that reads none (a plain door of a linear camera in a cell of 1.0,
    its edges admitting 2.70, was refused as uncertain to 0.10 mm, 0.001 mm off)."""
    from doorloc.vision.doubts import _within_claim

    assert _within_claim([1.35, 2.70], 1.0, 2.2) == [1.35, 2.2]
    assert _within_claim([0.3, 1.5, 1.5], 1.0, 2.2) == pytest.approx([1.0 / 2.2, 1.5])
    assert _within_claim([3.0], 2.0, 1.1) == [2.2]


def test_an_unambiguous_line_decides_which_reading_of_an_ambiguous_one_is_the_cameras():
    """A plain door of a 1.37 camera (the sharp set of ``bench_arris_range.py --seed 7000``, door 11031): its
    bottom end read 1.38 +- 0.11 and nothing else, its reference arris 3.64 +- 0.02 with 1.35 about as
    symmetric. Pooled as read, the sharper line won (3.57 +- 0.41) and the door was refused for the doubt;
    the bottom end decides: the reference arris is read at 1.35, the pool agrees with the camera. Where the
    first reading agrees with the deciding line within three joint sigmas it stands (1.42 +- 0.24 beside
    1.72 +- 0.20, for a 1.57 camera: its alternative 1.83 is no better told)."""
    bottom = LineResponse(1.377, 0.11, 0.3, 0.8, 0.0)
    reference = LineResponse(3.643, 0.0204, 0.3, 0.8, 0.0, alternatives=(1.349,))
    fit = combine_responses({"bottom": bottom, "reference": reference}, 1.368)
    assert fit is not None and fit.gamma == pytest.approx(1.351, abs=0.002) and fit.sigma < 0.05
    assert not fit.absorb and fit.alternatives == ()
    kept = LineResponse(1.42, 0.24, 0.3, 0.8, 0.0, alternatives=(0.84, 1.0, 1.83))
    pooled = combine_responses({"bottom": LineResponse(1.72, 0.2, 0.3, 0.8, 0.0), "reference": kept}, 1.57)
    w = np.array([1 / 0.2**2, 1 / 0.24**2])
    assert pooled is not None and pooled.gamma == pytest.approx(float(w @ [1.72, 1.42] / w.sum()))


def test_a_second_symmetric_exponent_is_reported():
    """The asymmetry is not monotone in the exponent: a linear camera's transition between plateaus 20 and
    230 grey levels, rounded to 8 bits under 0.1 grey level of noise (not dithered), is about as symmetric
    at ~1.7-1.9; under a grey level of noise the least asymmetry is the noise's, and one reading stands."""
    from doorloc.vision.response_asymmetry import Transitions, dithered, exponent_with_scatter

    rng = np.random.default_rng(1)
    n, w, s = 224, 21, 1.2
    lo, hi = 20.3 / 255, 230.6 / 255
    centre = 10 + np.linspace(-0.5, 0.5, n, endpoint=False)
    x = np.arange(w)

    def g(y):
        return y * ndtr(y / s) + s * np.exp(-0.5 * (y / s) ** 2) / math.sqrt(2 * math.pi)

    light = lo + (hi - lo) * (g(x[None, :] + 0.5 - centre[:, None]) - g(x[None, :] - 0.5 - centre[:, None]))
    raw = np.round((light + rng.normal(0, 0.1 / 255, light.shape)) * 255) / 255
    assert not dithered(raw, 255.0)
    found = exponent_with_scatter(Transitions(raw, -centre, dithered=False), np.repeat(np.arange(8), 28), 8)
    assert found is not None
    gamma, _, alternatives = found
    assert abs(gamma - 1.0) < 0.1
    assert alternatives and all(1.5 < a < 2.2 for a in alternatives)
    raw = np.round((light + rng.normal(0, 1.0 / 255, light.shape)) * 255) / 255
    assert dithered(raw, 255.0)
    found = exponent_with_scatter(Transitions(raw, -centre), np.repeat(np.arange(8), 28), 8)
    assert found is not None and abs(found[0] - 1.0) < 0.1 and found[2] == ()


def test_a_reading_and_an_unmeasured_claim_combine_by_their_sigmas():
    """A cell exponent nobody measured (1.0, known to +-1.2) and the image's reading: a precise reading
    keeps its own value and sigma, a weak one (read between the pixels) moves the exponent most of the way
    and keeps most of its sigma, and a reading no camera gives counts as the nearest one that does."""
    g, s = ResponseFit(1.01, 0.03, 1.0, ("bottom", "reference")).with_unmeasured_claim(1.2)
    assert g == pytest.approx(1.01, abs=0.001) and s == pytest.approx(0.03, rel=0.01)
    g, s = ResponseFit(1.65, 0.34, 1.0, ("reference",)).with_unmeasured_claim(1.2)  # square seed 9520
    assert 1.55 < g < 1.65 and 0.3 < s < 0.34
    g, _ = ResponseFit(0.7, 0.05, 1.0, ("bottom", "reference")).with_unmeasured_claim(1.2)
    assert g == pytest.approx(0.8, abs=0.01)


def test_what_the_lines_share_does_not_average_down():
    """Two edges square to the camera read through one lens: the interpolation's error (which follows the
    lens's spread) is the same on both, and their pooled sigma keeps it (two such readings of a 1.43
    camera, 1.26 +- 0.25 each, had pooled to +-0.18)."""
    a = LineResponse(1.26, 0.25, 0.1, 0.8, 0.0, True, shared_sigma=0.24)
    b = LineResponse(1.26, 0.25, 0.1, 0.8, 0.0, True, shared_sigma=0.24)
    both = combine_responses({"bottom": a, "reference": b}, 1.0)
    assert both is not None and both.sigma >= 0.24
    free = combine_responses(
        {"bottom": replace(a, shared_sigma=0.0), "reference": replace(b, shared_sigma=0.0)}, 1.0
    )
    assert free is not None and free.sigma == pytest.approx(0.25 / math.sqrt(2), rel=1e-6)


def test_a_measured_claim_holds_back_a_marginal_image_but_not_a_better_or_disagreeing_one():

    two = ("bottom", "reference")
    # Bouguet-like calibration 2.15 +- 0.12 against an image's 2.6 +- 0.1: 4.5 of the image's sigmas off
    # (absorbed when the cell's exponent is only stated), 2.9 joint sigmas (kept when it was measured)
    assert ResponseFit(2.6, 0.1, 2.15, two).absorb
    held = ResponseFit(2.6, 0.1, 2.15, two, claimed_sigma=0.12)
    assert not held.absorb and held.disagreement == pytest.approx(0.45 / math.hypot(0.1, 0.12))
    g, se, widened = held.combined
    assert g == pytest.approx((2.6 / 0.01 + 2.15 / 0.0144) / (1 / 0.01 + 1 / 0.0144))
    assert widened == pytest.approx(se * held.disagreement)
    # a claim 10 joint sigmas off, however tight, gives way; so does a loose one the image betters
    assert ResponseFit(2.2, 0.1, 1.0, two, claimed_sigma=0.02).absorb
    assert ResponseFit(2.2, 0.1, 1.0, two, claimed_sigma=0.5).absorb
    # and one edge is never enough
    assert not ResponseFit(2.2, 0.1, 1.0, ("bottom",), claimed_sigma=0.5).absorb


@pytest.mark.parametrize("camera_gamma", [1.0, 2.2])
def test_the_response_is_measured_on_calibration_boards(camera_gamma):
    """Rendered chessboard photographs (blur 0.8-1.5 px, read noise 1-2 grey levels, random poses): the
    median of the images' exponents is the camera's, within 3 of its sigma and 0.15."""
    from doorloc.cell import load_cell
    from doorloc.sim.boards import Checkerboard, render_board
    from doorloc.sim.effects import Effects
    from doorloc.vision.board_response import board_response

    cam = load_cell(Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml").camera
    board = Checkerboard(9, 6, 25.0)
    rng = np.random.default_rng(int(camera_gamma * 10))
    views = []
    while len(views) < 6:
        rvec = rng.uniform(-0.4, 0.4, 3)
        tvec = [rng.uniform(-150, 30), rng.uniform(-120, 20), rng.uniform(450, 700)]
        fx = Effects(gamma=camera_gamma, blur_sigma_px=rng.uniform(0.8, 1.5), read_noise_dn=rng.uniform(1, 2))
        rb = render_board(cam, board, rvec, tvec, effects=fx, seed=len(views))
        if rb.in_image.all():
            views.append((rb.image, rb.corners_px))
    r = board_response(views, 9, 6)
    assert r is not None and len(r.per_image) == 6
    assert abs(r.gamma - camera_gamma) <= min(3.0 * r.sigma, 0.15), (r.gamma, r.sigma, r.per_image)
    assert r.unmeasured_factor == pytest.approx(1.0 + 2.0 * r.sigma / r.gamma)
    assert board_response(views[:4], 9, 6) is None  # too few photographs to see their scatter


@pytest.mark.parametrize("top", [255.0, 65535.0])
def test_the_levels_of_whole_grey_levels_are_those_numpy_sorts(top):
    """Transitions.levels counts the grey levels present where the profiles are whole grey levels (the
    image's own): the same levels and index as ``np.unique`` over the floats, for 8 and 16 bits."""
    rng = np.random.default_rng(int(top))
    grey = rng.integers(0, int(top) + 1, size=(40, 17))
    grey[0, :3] = (0, int(top), 7)  # both ends of the scale present
    raw = grey.astype(np.float64) / top
    counted = Transitions(raw, np.zeros(40), top=top).levels
    sorted_ = Transitions(raw, np.zeros(40)).levels
    assert np.array_equal(counted[0], sorted_[0]) and counted[0].dtype == sorted_[0].dtype
    assert np.array_equal(counted[1], sorted_[1]) and counted[1].dtype == sorted_[1].dtype
