"""A response that rises over every stored level: the log-log bend (``curvature`` > 0) turns the response
back at ``ln g' = -gamma / (2 curvature)`` and the model holds it flat below. The model says how far above
the lowest stored level that is, and the model check's fit pays for it: a camera stores no levels that carry
no light."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.calib.detect import Chessboard
from doorloc.calib.io import CalibrationFile
from doorloc.photometric.check import check_boards
from doorloc.photometric.model import PhotometricModel
from doorloc.sim.boards import Checkerboard
from doorloc.sim.photometric import random_board_views

CAMERA = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)


@settings(max_examples=300, deadline=None)
@given(gamma=st.floats(0.3, 4.0), curvature=st.floats(-1.5, 1.5), black=st.floats(0.0, 0.2))
def test_the_flat_part_is_zero_exactly_where_every_stored_level_carries_more_light(gamma, curvature, black):
    m = PhotometricModel(gamma=gamma, curvature=curvature, black_level=black)
    flat = m.flat_response_ln_grey()
    # the stored levels above the pedestal, k / 255 of what lies over it (k = 1 .. 255)
    light = m.light_from_grey(black + np.arange(1, 256) / 255.0 * (1.0 - black))
    rises = bool(np.all(np.diff(light) > 0))
    if flat == 0.0:
        assert rises
    elif math.exp(flat) > 2.0 + 1e-6:
        # the levels below exp(flat) (at least the first two) are held at one light
        assert not rises and light[1] == light[0]
    assert flat >= 0.0


@pytest.mark.slow
def test_the_check_fits_no_response_that_holds_stored_levels_flat(tmp_path):
    # boards rendered by a camera that holds its darks flat (a bend of 0.26 on a linear camera: flat below
    # 37 grey, the dark squares stored at 0): the fit explained them by a bend of 1.40 on a power law of
    # 2.21, flat below 116 grey. Such a model would read a door's face darker than half scale as no light.
    seed = 35197
    model = PhotometricModel(curvature=0.2597934393918342)
    assert model.flat_response_ln_grey() > 3.0
    folder = tmp_path / "boards"
    folder.mkdir()
    for name, img in random_board_views(CAMERA, Checkerboard(9, 6, 25.0), model, 8, seed):
        cv2.imwrite(str(folder / name), img)
    c = check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
    assert c.model.flat_response_ln_grey() < 0.05, (c.causes, c.model.gamma, c.model.curvature)
