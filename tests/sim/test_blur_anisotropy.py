"""The renderer's blur that depends on the edge's direction draws the model's ``blur_anisotropy`` as the model
defines it (the variance added across vertical edges and taken off across horizontal ones), so the check reads
back what was rendered (a renderer that added half of it did not)."""

from __future__ import annotations

import numpy as np
import pytest

from doorloc.calib.camera import CameraModel
from doorloc.photometric.board_edges import measure_board_edges
from doorloc.photometric.model import PLAIN, PhotometricModel
from doorloc.photometric.profiles import fit_profiles
from doorloc.sim.boards import Checkerboard
from doorloc.sim.photometric import CameraRendering, render_photographed_board

CAMERA = CameraModel.from_values([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [0, 0, 0, 0, 0], (640, 480))


@pytest.mark.parametrize("anisotropy", [-0.4, 0.0, 0.5])
def test_the_rendered_anisotropy_is_the_models(anisotropy):
    rb = render_photographed_board(
        CAMERA,
        Checkerboard(9, 6, 25.0),
        np.array([0.05, -0.05, 0.02]),
        np.array([-100.0, -62.5, 450.0]),
        PhotometricModel(blur_anisotropy=anisotropy),
        CameraRendering(1.0, 0.8, 0.3),
        seed=1,
    )
    e = measure_board_edges(rb.image, rb.corners_px, 9, 6, 25.0, CAMERA)
    blur2 = fit_profiles(e, PLAIN, np.isfinite(e.offset_px)).blur_px ** 2
    cos2 = e.normal[:, 0] ** 2 - e.normal[:, 1] ** 2
    vertical, horizontal = np.nanmedian(blur2[cos2 > 0.5]), np.nanmedian(blur2[cos2 < -0.5])
    # sigma^2 = s + anisotropy cos(2 phi): the two directions differ by twice it
    assert abs((vertical - horizontal) / 2 - anisotropy) < 0.05
