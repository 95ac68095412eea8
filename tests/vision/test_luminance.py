"""A colour camera's luminance: the channels summed in light, not in stored levels."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from doorloc.vision.luminance import BGR_WEIGHTS, ImageFormatError, luminance_plane


@settings(max_examples=60, deadline=None)
@given(
    gamma=st.floats(0.8, 2.6),
    eight_bit=st.booleans(),
    levels=arrays(np.int64, (8, 9, 3), elements=st.integers(0, 65535)),
)
def test_a_colour_images_channels_are_summed_in_light(gamma, eight_bit, levels):
    """At an exponent other than 1 the plane holds, in 16-bit power-law levels, the light of the channels
    summed with BT.601's weights (within one code of the exact level: the table's interpolation); a grey
    pixel (three equal channels) keeps its level; BGRA's alpha is not read."""
    top = 255 if eight_bit else 65535
    img = (levels % (top + 1)).astype(np.uint8 if eight_bit else np.uint16)
    img[0] = img[0, :, :1]  # a row of grey pixels
    # (a 16-bit camera that says so: its image may be as dark as it likes)
    depth = None if eight_bit else 16
    lum = luminance_plane(img, gamma, depth)
    assert lum.plane.dtype == np.uint16 and lum.scale_to_8bit == pytest.approx(255 / 65535)
    light = (img / top) ** gamma @ np.array(BGR_WEIGHTS)
    np.testing.assert_allclose(lum.plane, light ** (1 / gamma) * 65535, atol=1.01)
    np.testing.assert_allclose(lum.plane[0], img[0, :, 0] / top * 65535, atol=1.01)
    alpha = np.concatenate([img, np.zeros_like(img[..., :1])], axis=2)
    np.testing.assert_array_equal(luminance_plane(alpha, gamma, depth).plane, lum.plane)


@pytest.mark.parametrize("light_gamma", [1.0, None])
def test_at_a_linear_response_or_none_the_sum_is_opencvs_8_bit_one(light_gamma):
    """At an exponent of 1 the stored levels are light, and without one (the overlay's picture) they are
    summed as stored: OpenCV's fixed-point BT.601 sum, 8-bit."""
    img = np.random.default_rng(3).integers(0, 256, (12, 16, 3), dtype=np.uint8)
    lum = luminance_plane(img, light_gamma)
    assert lum.plane.dtype == np.uint8 and lum.scale_to_8bit == 1.0
    np.testing.assert_array_equal(lum.plane, cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))
    grey = img[..., 1]
    assert luminance_plane(grey, 2.2).plane is grey


def test_summed_in_levels_a_colour_edge_bends_as_a_wrong_exponent_bends_it():
    """Two channels blurred apart across one edge (as a single-chip camera interpolates them), stored at
    an exponent of 2: summed in stored levels the edge's light is no blurred step (up to 3.7 % of the
    contrast off the channels' weighted step), summed in light it is that step."""
    x = np.linspace(-4, 4, 81)
    sharp, soft = 1 / (1 + np.exp(-x / 0.3)), 1 / (1 + np.exp(-x / 1.2))  # light, 0..1
    bgr = np.zeros((8, 81, 3))
    bgr[..., 0], bgr[..., 1], bgr[..., 2] = soft, sharp, soft
    stored = np.rint(np.sqrt(bgr) * 65535).astype(np.uint16)
    w = np.array(BGR_WEIGHTS)
    true_light = bgr[0] @ w
    in_light = (luminance_plane(stored, 2.0).plane[0] / 65535.0) ** 2
    in_levels = ((stored[0] / 65535.0) @ w) ** 2
    np.testing.assert_allclose(in_light, true_light, atol=1e-4)
    assert np.abs(in_levels - true_light).max() > 0.03


@pytest.mark.parametrize("bits", [8, 10, 12, 14])
def test_a_cameras_stored_depth_is_brought_to_the_16_bit_scale(bits):
    """A camera that stores ``bits`` of levels from 0 in 16-bit images (``camera.stored_bits``): every level
    ``v`` becomes ``round(v * 65535 / top)``, full scale to full scale, exactly (OpenCV's multiply against
    numpy's rounding, every level); one stored level is ``255 / top`` on the 0-255 scale, for the rounding's
    doubt; a colour image's channels are read over the same full scale."""
    top = (1 << bits) - 1
    grey = np.arange(top + 1, dtype=np.uint16).reshape(1, -1)
    grey = np.repeat(grey, 8, axis=0)
    lum = luminance_plane(grey, 2.2, bits)
    assert lum.plane.dtype == np.uint16 and lum.scale_to_8bit == pytest.approx(255 / 65535)
    np.testing.assert_array_equal(lum.plane[0], np.rint(np.arange(top + 1) * 65535.0 / top))
    assert lum.level_8bit == pytest.approx(255 / top)
    colour = np.random.default_rng(bits).integers(0, top + 1, (8, 9, 3)).astype(np.uint16)
    light = (colour / top) ** 2.2 @ np.array(BGR_WEIGHTS)
    np.testing.assert_allclose(
        luminance_plane(colour, 2.2, bits).plane, light ** (1 / 2.2) * 65535, atol=1.01
    )
    opaque = np.concatenate([colour, np.full_like(colour[..., :1], 65535)], axis=2)  # (alpha at 16 bits)
    np.testing.assert_array_equal(
        luminance_plane(opaque, 2.2, bits).plane, luminance_plane(colour, 2.2, bits).plane
    )
    full = luminance_plane(np.full((8, 8), 65535, np.uint16), 2.2)
    assert full.level_8bit == full.scale_to_8bit == pytest.approx(255 / 65535)


def test_a_level_the_stated_depth_cannot_hold_is_refused():
    """A cell that says 12 bits for a camera whose image holds a level above 4095 states the wrong depth: the
    image is refused with the level and the key, not read with a scale that clips it."""
    img = np.full((8, 8), 1000, np.uint16)
    img[0, 0] = 5000
    with pytest.raises(ImageFormatError, match=r"level 5000, above the 12 bits .*camera\.stored_bits: 12"):
        luminance_plane(img, 1.0, 12)


@pytest.mark.parametrize(("brightest", "bits"), [(900, 10), (3000, 12), (4095, 12)])
def test_a_16_bit_image_within_12_bits_asks_for_the_cameras_depth(brightest, bits):
    """Without ``camera.stored_bits`` a 16-bit image whose levels all stay within 12 bits (above 255: a black
    image is the gate's to name) is refused, the depth asked for; read on 65535's scale every threshold would
    be 16 times too strict. Above 4095, or stated, it is read."""
    img = np.full((8, 8), 300, np.uint16)
    img[0, 0] = brightest
    with pytest.raises(ImageFormatError, match=rf"camera\.stored_bits: {bits} in the cell"):
        luminance_plane(img)
    assert luminance_plane(img, None, bits).plane[0, 0] == round(brightest * 65535 / ((1 << bits) - 1))
    img[0, 0] = 4096
    assert luminance_plane(img).plane[0, 0] == 4096
    assert luminance_plane(np.full((8, 8), 200, np.uint16)).plane[0, 0] == 200
