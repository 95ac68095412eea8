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
from doorloc.vision.side_patches import plateau_noise_dn


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
def test_the_images_noise_is_read_beside_its_lines_without_the_light_slope_or_rounding(noise):
    """Lit ramps (the shading across a patch), rounded to levels: their noise reads as drawn, 0 without
    noise, from the centre of each patch; a patch at a whole level under little noise reads low, so the
    most of them is the image's."""
    rng = np.random.default_rng(4)
    rows, cols = np.mgrid[0:48, 0:128]
    ramp = 90.3 + 0.05 * rows + 0.02 * cols
    noisy = np.clip(np.round(ramp + rng.normal(0.0, noise, ramp.shape)), 0, 255).astype(np.uint8)
    flat = np.full((48, 128), 40, np.uint8)  # a whole level, no noise shown
    got = plateau_noise_dn({False: {"far": flat, "bottom": flat}, True: {"far": noisy}}, 1.0)
    assert got == pytest.approx(noise, abs=0.12)
    assert plateau_noise_dn({False: {}, True: {}}, 1.0) == 0.0


def test_a_noise_free_doors_response_is_not_read_off_its_rounded_transitions(cell):
    """A linear camera's door rendered without noise (step 37, blur 1.1 px, 0.73 deg): its plain edges'
    undithered rounding bent their transitions into a 2.19 +- 0.03 camera exponent, which replaced the
    cell's right 1.0: x 0.11 mm off at 17 sigma. Its plateaus are now too quiet to read the response from,
    and the cell's exponent stands within its unmeasured factor; with 0.3 grey of noise it is read again."""
    door = DoorSize(900, 82.07498858492811, 2100)
    pose = DoorPose(9.486162125481133, -2.8398882582067264, -0.7266609562055439)
    eff = Effects(
        albedo_hinge=0.42000803726736163,
        albedo_side=0.11067400934563115,
        albedo_background=0.0807334159735728,
        vignetting=0.0017127682261638634,
        gradient_u=0.0309307561351011,
        blur_sigma_px=1.11588518999395,
    )
    cfg = replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0)
    r = locate(render_door(cell, door, pose, effects=eff, seed=5561).image, cell, door, config=cfg)
    assert r.ok and r.uncertainty is not None
    response = r.diagnostics["camera_response"]
    assert response["used"] == "cell" and not response["checked"]
    assert "quieter" in response["unchecked_because"]
    assert abs(r.x_mm - pose.x_mm) <= 3.0 * r.uncertainty.x_mm, (r.x_mm - pose.x_mm, r.uncertainty)
    assert abs(r.z_mm - pose.z_mm) <= 3.0 * r.uncertainty.z_mm, (r.z_mm - pose.z_mm, r.uncertainty)
    noisy = replace(eff, read_noise_dn=0.3)
    r = locate(render_door(cell, door, pose, effects=noisy, seed=5561).image, cell, door, config=cfg)
    assert r.ok and r.diagnostics["camera_response"]["checked"]
    assert abs(r.x_mm - pose.x_mm) < 0.01
