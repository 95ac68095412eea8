"""Grey-level rounding that no noise dithers: its doubt, and a door it would have put 6.5 sigma off."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.vision.locate import locate
from doorloc.vision.quantisation import QUANTISATION_DRIFT_TILT, quantisation_doubt_px, quantisation_tilt
from doorloc.vision.side_patches import line_noise_dn


@given(
    st.floats(5.0, 200.0),
    st.integers(3, 25),
    st.floats(0.0, 0.6),
    st.floats(0.01, 0.3),
)
def test_the_doubt_falls_with_noise_and_contrast_and_grows_with_the_window(step, window, noise, more):
    d = quantisation_doubt_px(step, window, noise)
    assert 0.0 < d <= math.sqrt(window / 12.0) / step
    assert quantisation_doubt_px(step, window, noise + more) < d
    assert quantisation_doubt_px(step * (1.0 + more), window, noise) < d
    assert quantisation_doubt_px(step, window + 2, noise) > d


def test_a_sixteen_bit_image_or_a_noisy_one_is_not_doubted():
    assert quantisation_doubt_px(32.0, 7, 0.0, level_dn=255 / 65535) < 0.01 * quantisation_doubt_px(
        32.0, 7, 0.0
    )
    assert quantisation_doubt_px(32.0, 7, 0.8) < 1e-5
    assert quantisation_doubt_px(math.nan, 7, 0.0) == quantisation_doubt_px(0.0, 7, 0.0) == 0.0


def test_the_tilt_is_the_drift_over_the_lines_length():
    scan = np.arange(100.0, 780.0)
    assert quantisation_tilt(0.02, scan) == pytest.approx(QUANTISATION_DRIFT_TILT * 0.02 / 679.0)
    assert quantisation_tilt(0.02, scan[:1]) == quantisation_tilt(0.0, scan) == 0.0


@pytest.fixture(scope="module")
def cell(thesis_cell_path):
    return load_cell(thesis_cell_path)


DOOR = DoorSize(900, 56.77066128942, 2100)
POSE = DoorPose(2.8930619351844005, 3.99042089670834, 0.012418589461225427)
EFFECTS = Effects(
    albedo_hinge=0.271051353736383,
    albedo_side=0.4848580980545652,
    albedo_background=0.1444152948706044,
    vignetting=0.1420858141449983,
    gradient_u=-0.06136670487733725,
    blur_sigma_px=1.0229467893333049,
)


def test_a_noise_free_door_square_to_the_pixels_claims_the_yaw_its_rounding_allows(cell):
    """This plain door 0.012 deg from square, step 32 grey levels, with vignetting, rendered without noise:
    its far arris reads in runs a whole level over the step apart (1/32 px), 0.125 px from the same door
    unvignetted at one end; answered 0.0105 deg off in yaw at 6.5 sigma before the rounding was doubted.
    With read noise of 2 levels the rounding is dithered and no such doubt is claimed."""
    cfg = replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0)
    r = locate(render_door(cell, DOOR, POSE, effects=EFFECTS, seed=1336).image, cell, DOOR, config=cfg)
    assert r.ok and r.uncertainty is not None
    sources = {b["source"] for b in r.diagnostics["uncertainty_budget"]}
    assert any("quantisation" in s for s in sources), sources
    assert abs(r.yaw_deg - POSE.yaw_deg) <= 3.0 * r.uncertainty.yaw_deg, (
        r.yaw_deg - POSE.yaw_deg,
        r.uncertainty,
    )
    noisy = replace(EFFECTS, read_noise_dn=2.0)
    r = locate(render_door(cell, DOOR, POSE, effects=noisy, seed=1336).image, cell, DOOR, config=cfg)
    assert r.ok and not any("quantisation" in b["source"] for b in r.diagnostics["uncertainty_budget"])


@pytest.mark.parametrize("noise", [0.0, 0.7, 1.5])
def test_a_lines_noise_is_read_beside_it_without_its_light_slope_or_rounding(noise):
    """A lit ramp (the shading across a patch), rounded to levels: its noise reads as drawn, 0 without
    noise; the quieter side is the line's."""
    rng = np.random.default_rng(4)
    rows, cols = np.mgrid[0:48, 0:128]
    ramp = 90.0 + 0.05 * rows + 0.02 * cols
    loud = np.clip(np.round(ramp + rng.normal(0.0, 3.0, ramp.shape)), 0, 255).astype(np.uint8)
    quiet = np.clip(np.round(ramp + rng.normal(0.0, noise, ramp.shape)), 0, 255).astype(np.uint8)
    got = line_noise_dn({False: {"far": quiet}, True: {"far": loud, "bottom": loud}}, 1.0)
    assert set(got) == {"far", "bottom"}
    assert got["far"] == pytest.approx(noise, abs=0.12)
    assert got["bottom"] == pytest.approx(3.0, rel=0.15)
