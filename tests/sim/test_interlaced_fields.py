"""The renderer's interlaced fields: each even row samples the optics' image half the offset away and each odd
row half of it the other way, to a fraction of a grey level (a warp that rounds the shift would not)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ndtr

from doorloc.photometric.model import PhotometricModel
from doorloc.sim.photometric import CameraRendering, apply_camera


def _blurred_step(edge_row: float, shape=(64, 48), blur_px: float = 1.1) -> np.ndarray:
    """The light of a dark-to-light step across the rows at ``edge_row`` (px) through a Gaussian blur, exact
    at each pixel (0.1 -> 0.9): the image the fields sample, given to the camera with no blur of its own."""
    rows = np.arange(shape[0], dtype=float)[:, None]
    return np.broadcast_to(0.1 + 0.8 * ndtr((rows - edge_row) / blur_px), shape).copy()


@pytest.mark.parametrize("dv", [0.06, 0.159, -0.23])
def test_each_field_samples_the_image_half_the_offset_away(dv):
    plain, sharp = PhotometricModel(), CameraRendering(blur_px=0.0)
    out = apply_camera(_blurred_step(31.3), plain, CameraRendering(blur_px=0.0, fields=(0.0, dv))).astype(int)
    # even rows sample the image dv/2 further down: the step appears dv/2 higher; odd rows the other way
    even = apply_camera(_blurred_step(31.3 - dv / 2), plain, sharp).astype(int)
    odd = apply_camera(_blurred_step(31.3 + dv / 2), plain, sharp).astype(int)
    inner = slice(3, -3)
    assert np.abs(out[0::2][inner] - even[0::2][inner]).max() <= 1
    assert np.abs(out[1::2][inner] - odd[1::2][inner]).max() <= 1
    # and the fields differ where the step is: the offset is drawn, not lost
    assert np.abs(even - odd).max() >= 5


def test_a_model_with_fields_draws_its_mean_where_the_photograph_states_none():
    model = PhotometricModel(field_offset_v_px=0.2)
    stated = apply_camera(_blurred_step(31.3), model, CameraRendering(blur_px=1.0, fields=(0.0, 0.2)))
    from_model = apply_camera(_blurred_step(31.3), model, CameraRendering(blur_px=1.0))
    none = apply_camera(_blurred_step(31.3), PhotometricModel(), CameraRendering(blur_px=1.0))
    assert np.array_equal(stated, from_model)
    assert not np.array_equal(from_model, none)
