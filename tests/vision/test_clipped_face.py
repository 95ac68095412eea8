"""A camera that saturates below the top code: a sensor or tone curve that stores every light beyond 240 grey at
240 leaves an overexposed hinge face flat there, under the 249 the white check reads, and its edges lie towards
the dark side. Locate refuses it ``overexposed`` by the sensor's noise, which the clip takes from the bright side
and leaves on the dark one; a chamfer's strip lit brighter than the face is read alike, inside its borders."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from doorloc.cell import DoorSize, load_cell
from doorloc.photometric.model import PhotometricModel
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.sim.photometric import CameraRendering, apply_camera
from doorloc.vision.config import LocateConfig
from doorloc.vision.locate import locate
from doorloc.vision.quality import SideNoise, beyond_two_share, check_clipped_flat, side_noise

CELL = dataclasses.replace(
    load_cell(Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml"), response_gamma=2.2
)
#: a video camera (power law 2.2) whose sensor saturates at 240 of 255 grey
CLIPS_AT_240 = PhotometricModel(gamma=2.2, clip_level=240 / 255)


def test_a_clip_is_flat_where_a_sensors_noise_is_not():
    rng = np.random.default_rng(5)
    lit = np.clip(np.rint(200 + rng.normal(0, 1.0, (48, 128))), 0, 255).astype(np.uint8)
    clipped = np.full((48, 128), 240, np.uint8)
    noisy, flat = side_noise([lit], 1.0), side_noise([clipped], 1.0)
    assert noisy.flat_share < 0.5 and abs(noisy.sigma - 1.0) < 0.1 and abs(noisy.level - 200) <= 1
    assert flat.flat_share == 1.0 and flat.sigma == 0.0 and flat.level == 240
    # JPEG decodes a block of one level to that level, and keeps a noisy one spread
    for patch, is_flat in ((clipped, True), (lit, False)):
        ok, buf = cv2.imencode(".jpg", patch, [cv2.IMWRITE_JPEG_QUALITY, 88])
        seen = side_noise([cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)], 1.0)
        assert ok and (seen.flat_share >= 0.95) == is_flat
    assert noisy.beyond_two > 0.3 and flat.beyond_two == 0.0
    # a level near a rounding boundary under a tiny noise splits over two levels: nothing beyond them
    dithered = np.where(rng.random((48, 128)) < 0.3, 49, 48).astype(np.uint8)
    assert side_noise([dithered], 1.0).beyond_two == 0.0 == beyond_two_share([dithered], 1.0)
    assert beyond_two_share([lit], 1.0) == noisy.beyond_two and beyond_two_share([], 1.0) == 0.0
    # a smooth ramp rounded to grey levels carries no noise, however its levels step
    cols = np.arange(128)[None, :].repeat(48, 0)
    ramp = side_noise([np.rint(40 + 0.3 * cols).astype(np.uint8)], 1.0)
    assert ramp.sigma < 0.1 and ramp.flat_share < 0.2
    # 16-bit planes are read on their 8-bit scale
    assert side_noise([clipped.astype(np.uint16) * 257], 1 / 257).flat_share == 1.0
    assert side_noise([], 1.0) is None


def _side(share: float, sigma: float, level: float, beyond_two: float = 0.3) -> SideNoise:
    return SideNoise(share, sigma, level, beyond_two)


@pytest.mark.parametrize(
    "bright,dark,gamma,refused",
    [
        # a clip beside a noisy dark side: refused, at any response
        (_side(1.0, 0.0, 240), _side(0.3, 1.5, 150), 1.0, True),
        (_side(1.0, 0.0, 240), _side(0.3, 1.5, 150), 2.2, True),
        (_side(0.96, 0.2, 240), _side(0.6, 0.5, 60), 1.0, True),
        # noise-free both sides (a clean render): nothing to tell a clip by
        (_side(1.0, 0.0, 200), _side(1.0, 0.0, 80), 2.2, False),
        # a quiet camera whose response shrinks the read noise on the bright side: 0.7 grey at 82 is
        # 0.29 at 194 through 2.0, which rounds to one level almost everywhere
        (_side(1.0, 0.07, 194), _side(0.45, 0.7, 82), 2.01, False),
        # the same dark side with a linear response: 0.7 grey stays 0.7 and would spread the face
        (_side(1.0, 0.07, 194), _side(0.45, 0.7, 82), 1.0, True),
        # a dark side too quiet to tell by (0.25 grey)
        (_side(1.0, 0.0, 81), _side(0.9, 0.25, 40), 1.0, False),
        # a dark side split over two levels: a level near a rounding boundary under a noise too small to read
        (_side(1.0, 0.0, 81), _side(0.69, 0.36, 48, 0.0), 1.0, False),
        # a face with noise of its own
        (_side(0.87, 0.35, 231), _side(0.42, 0.86, 111), 2.21, False),
        # a black dark side tells nothing
        (_side(1.0, 0.0, 240), _side(1.0, 0.0, 0), 2.2, False),
    ],
)
def test_a_flat_bright_side_is_refused_only_where_the_dark_sides_noise_would_spread_it(
    bright, dark, gamma, refused
):
    r = check_clipped_flat(bright, dark, gamma, 0.95, bright.level)
    assert (r is not None) == refused
    if refused:
        assert r.code == "overexposed" and "clipped" in r.message and "exposure" in r.message
    assert check_clipped_flat(None, dark, gamma, 0.95, 255.0) is None
    assert check_clipped_flat(bright, None, gamma, 0.95, 255.0) is None
    # a clip caps every light: a flat side below the brightest plateau the edges see is a smooth surface
    assert check_clipped_flat(bright, dark, gamma, 0.95, bright.level + 10.0) is None


def _photograph(exposure: float, seed: int, pose: DoorPose, door: DoorSize) -> np.ndarray:
    radiance = render_door(
        CELL, door, pose, effects=Effects(albedo_hinge=0.5, albedo_background=0.12), seed=seed
    ).radiance
    scale = exposure / float(np.percentile(radiance, 99.5))
    return apply_camera(
        radiance, CLIPS_AT_240, CameraRendering(blur_px=1.0, exposure=scale, read_noise=1.5), seed
    )


@pytest.mark.parametrize("seed,pose", [(3, (-4.0, 6.0, 1.1)), (4, (7.5, -3.0, -1.6))])
def test_a_face_clipped_below_white_is_refused_and_one_exposed_right_is_answered(seed, pose):
    door, truth = DoorSize(900, 50.0, 2100), DoorPose(*pose)
    over = _photograph(1.4, seed, truth, door)  # the face's light 1.4x what stores 255 before the clip
    r = locate(over, CELL, door)
    assert not r.ok and r.error_code == "overexposed" and "clipped" in r.error, r.error
    # why it is refused: with the check off, the same photograph is answered off by more than its sigma
    off = locate(over, CELL, door, config=dataclasses.replace(CELL.locate, clipped_flat_share=1.01))
    assert off.ok, off.error
    assert abs(off.x_mm - truth.x_mm) > 2 * off.uncertainty.x_mm
    # the same door with its face below the clip
    right = locate(_photograph(0.85, seed, truth, door), CELL, door)
    assert right.ok, right.error
    assert abs(right.x_mm - truth.x_mm) <= 2 * right.uncertainty.x_mm
    assert abs(right.z_mm - truth.z_mm) <= 2 * right.uncertainty.z_mm


def test_the_clip_check_is_a_validated_setting():
    with pytest.raises(ValueError, match="clipped_flat_share"):
        LocateConfig(clipped_flat_share=0.0)


#: a camera of 1.8 whose sensor saturates at 230 of 255 grey
CLIPS_AT_230 = PhotometricModel(gamma=1.8, clip_level=0.9)
CELL_18 = dataclasses.replace(CELL, response_gamma=1.8, response_gamma_sigma=0.05)


@pytest.mark.parametrize("seed,pose", [(5, (-2.0, -1.5, 0.7)), (6, (6.0, 4.0, -1.2))])
def test_a_chamfer_strip_clipped_below_white_is_refused_where_the_face_is_not(seed, pose):
    """A chamfer lit brighter than the face (the renderer's chamfer albedo 0.66 against a face of 0.31)
    clips at 230 while the face below it keeps its noise: no patch beside the edges reaches the strip, and
    its white check counts the top code, which this camera never stores."""
    door, truth = DoorSize(900, 40.0, 2100, 2.0, "chamfer"), DoorPose(*pose)
    radiance = render_door(
        CELL_18, door, truth, effects=Effects(albedo_hinge=0.31, albedo_background=0.13), seed=seed
    ).radiance

    def photograph(exposure: float) -> np.ndarray:
        scale = exposure / float(np.percentile(radiance, 99.5))  # the strips' light
        return apply_camera(
            radiance, CLIPS_AT_230, CameraRendering(blur_px=1.5, exposure=scale, read_noise=2.5), seed
        )

    over = photograph(1.5)
    # the strips clip, not the face (a clipped face would hold far more of the frame)
    assert 0 < np.mean(over == 230) < 0.02
    r = locate(over, CELL_18, door)
    assert not r.ok and r.error_code == "overexposed", r.error
    assert "arris strip" in r.error and "clipped at 230" in r.error, r.error
    # a cell told the camera's clip reads the strips at it
    told = locate(over, dataclasses.replace(CELL_18, camera_photometry=CLIPS_AT_230), door)
    assert not told.ok and "arris strip" in told.error and "the camera's clip (230 grey)" in told.error
    # why: with the check off the same photograph is answered a quarter of a millimetre off, near 6 sigma
    off = locate(over, CELL_18, door, config=dataclasses.replace(CELL_18.locate, clipped_flat_share=1.01))
    assert off.ok, off.error
    assert abs(off.x_mm - truth.x_mm) > 2 * off.uncertainty.x_mm
    # the strips under the clip (0.75 of the light that stores 230: 217 grey): not refused as clipped, and
    # answered within 2 sigma where the cell lets a pose uncertain to 0.12 mm pass
    right = locate(
        photograph(0.75), CELL_18, door, config=dataclasses.replace(CELL_18.locate, max_uncertainty_mm=0.2)
    )
    assert right.ok, right.error
    assert abs(right.x_mm - truth.x_mm) <= 2 * right.uncertainty.x_mm
    assert abs(right.z_mm - truth.z_mm) <= 2 * right.uncertainty.z_mm


@pytest.mark.parametrize("seed,pose", [(3, (-4.0, 6.0, 1.1)), (4, (7.5, -3.0, -1.6))])
def test_a_clip_the_cells_camera_model_states_is_read_where_the_image_shows_no_noise(seed, pose):
    """JPEG 88 over half a grey level of read noise leaves neither side of the edges any noise: a face flat at
    the clip cannot be told from a clean one, and is answered off by several sigma. A cell whose camera model
    states the clip (``clip_level``, as ``doorloc check-model --boards`` writes it) refuses it; below the
    clip its answer is the plain cell's."""
    door, truth = DoorSize(900, 50.0, 2100), DoorPose(*pose)
    radiance = render_door(
        CELL, door, truth, effects=Effects(albedo_hinge=0.5, albedo_background=0.12), seed=seed
    ).radiance
    told = dataclasses.replace(CELL, camera_photometry=CLIPS_AT_240)

    def photograph(exposure: float) -> np.ndarray:
        scale = exposure / float(np.percentile(radiance, 99.5))
        rendering = CameraRendering(blur_px=1.0, exposure=scale, read_noise=0.5, jpeg_quality=88)
        return apply_camera(radiance, CLIPS_AT_240, rendering, seed)

    over = photograph(1.4)
    plain = locate(over, CELL, door)
    assert plain.ok, plain.error
    assert abs(plain.x_mm - truth.x_mm) > 2 * plain.uncertainty.x_mm
    r = locate(over, told, door)
    assert not r.ok and r.error_code == "overexposed" and "camera's clip (240 grey" in r.error, r.error
    under = photograph(0.85)
    a, b = locate(under, CELL, door), locate(under, told, door)
    assert a.ok and b.ok, (a.error, b.error)
    assert (a.x_mm, a.z_mm, a.yaw_deg, a.uncertainty) == (b.x_mm, b.z_mm, b.yaw_deg, b.uncertainty)
    assert abs(b.x_mm - truth.x_mm) <= 2 * b.uncertainty.x_mm


def test_a_frame_washed_out_to_a_stated_clip_is_refused_as_saturated():
    """Door and background both beyond a clip at 240 store one level: without the clip stated the frame reads as
    one without contrast (check the lighting), with it as saturated (reduce the exposure), as at 255."""
    door = DoorSize(900, 50.0, 2100)
    radiance = render_door(
        CELL, door, DoorPose(1.0, 2.0, 0.3), effects=Effects(albedo_hinge=0.5, albedo_background=0.45), seed=3
    ).radiance
    scale = 1.4 / float(np.percentile(radiance, 99.5))
    img = apply_camera(
        radiance, CLIPS_AT_240, CameraRendering(blur_px=1.0, exposure=scale, read_noise=0.5), 3
    )
    assert locate(img, CELL, door).error_code == "low_contrast"
    told = locate(img, dataclasses.replace(CELL, camera_photometry=CLIPS_AT_240), door)
    assert told.error_code == "saturated_image", told.error
