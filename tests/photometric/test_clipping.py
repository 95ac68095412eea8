"""The sensor's clip level: the renderer stores light beyond it at that level, the model file validates it,
and an edge whose bright square is clipped is the one the censored fit re-places."""

from __future__ import annotations

import numpy as np
import pytest

from doorloc.calib.camera import CameraModel
from doorloc.photometric.board_edges import measure_board_edges
from doorloc.photometric.clipping import clipped_lines
from doorloc.photometric.model import PhotometricModel
from doorloc.sim.boards import Checkerboard
from doorloc.sim.photometric import CameraRendering, render_photographed_board

CAMERA = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)


def _board(clip: float, exposure: float):
    rvec = np.array([0.1, -0.2, 0.05])
    tvec = -np.array([100.0, 62.5, 0.0]) + np.array([0.0, 0.0, 450.0])
    model = PhotometricModel(clip_level=clip)
    return render_photographed_board(
        CAMERA, Checkerboard(9, 6, 25.0), rvec, tvec, model, CameraRendering(0.8, exposure, 0.5), seed=3
    )


@pytest.mark.parametrize("clip", [0.55, 0.7, 0.9])
def test_renderer_stores_light_beyond_the_clip_at_the_clip(clip):
    rb = _board(clip, 1.05)  # the light squares reach 0.945 of full scale
    top = int(np.rint(clip * 255))
    assert rb.image.max() <= top
    # the clipped squares pile at the clip level
    assert (rb.image == top).mean() > 0.1


def test_only_edges_whose_bright_square_reaches_the_clip_count_as_clipped():
    rb = _board(0.7, 0.85)
    e = measure_board_edges(rb.image, rb.corners_px, 9, 6, 25.0, CAMERA)
    clipped = clipped_lines(e, 0.7)
    assert clipped.mean() > 0.9
    # the area estimator moves clipped edges towards the dark side
    assert np.nanmedian(e.offset_px[clipped]) < -0.05
    dim = _board(0.7, 0.6)
    e2 = measure_board_edges(dim.image, dim.corners_px, 9, 6, 25.0, CAMERA)
    assert not clipped_lines(e2, 0.7).any()
    assert abs(np.nanmedian(e2.offset_px)) < 0.02


def test_model_file_validates_the_clip_level():
    assert PhotometricModel.from_dict({"clip_level": 0.8}).clips
    assert not PhotometricModel().clips
    with pytest.raises(ValueError, match="clip_level"):
        PhotometricModel.from_dict({"clip_level": 1.2})
    g = PhotometricModel(clip_level=0.6).grey_from_light(np.array([0.3, 0.6, 0.9]))
    assert np.allclose(g, [0.3, 0.6, 0.6], atol=1e-3)
