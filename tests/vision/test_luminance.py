"""A colour camera's luminance: the channels summed in light, not in stored levels."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from doorloc.vision.luminance import BGR_WEIGHTS, luminance_plane


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
    lum = luminance_plane(img, gamma)
    assert lum.plane.dtype == np.uint16 and lum.scale_to_8bit == pytest.approx(255 / 65535)
    light = (img / top) ** gamma @ np.array(BGR_WEIGHTS)
    np.testing.assert_allclose(lum.plane, light ** (1 / gamma) * 65535, atol=1.01)
    np.testing.assert_allclose(lum.plane[0], img[0, :, 0] / top * 65535, atol=1.01)
    alpha = np.concatenate([img, np.zeros_like(img[..., :1])], axis=2)
    np.testing.assert_array_equal(luminance_plane(alpha, gamma).plane, lum.plane)


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
