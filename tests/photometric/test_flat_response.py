"""A response that rises over every stored level: the log-log bend (``curvature`` > 0) turns the response
back at ``ln g' = -gamma / (2 curvature)`` and the model holds it flat below. The model says how far above
the lowest stored level that is, and the model check's fit pays for it: a camera stores no levels that carry
no light. Nor may its pedestal lie above the dark squares the camera stores: it reads them as no light."""

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
from doorloc.photometric.board_edges import darkest_plateau
from doorloc.photometric.catalogue import CAUSES_BY_NAME
from doorloc.photometric.check import check_boards, measure_boards
from doorloc.photometric.fit import fit_causes
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


@settings(max_examples=200, deadline=None)
@given(gamma=st.floats(0.3, 4.0), black=st.floats(0.0, 0.3), darkest=st.floats(0.0, 0.3))
def test_the_pedestal_is_paid_for_exactly_where_it_reads_a_stored_dark_square_as_no_light(
    gamma, black, darkest
):
    m = PhotometricModel(gamma=gamma, black_level=black)
    over = m.pedestal_over_darks_ln_grey(darkest)
    assert over >= 0.0
    if over == 0.0:
        assert black <= max(darkest, 1.0 / 255.0)
    else:
        # a dark square stored at ``darkest`` is read as no light
        assert m.light_from_grey(np.array([darkest]))[0] == 0.0
    if over > 0.0:
        assert m.with_values(black_level=min(0.99, black * 1.1)).pedestal_over_darks_ln_grey(darkest) > over


def test_the_fit_puts_no_pedestal_above_bouguets_dark_squares(shared_data):
    # a toe and a shoulder fitted to the places of Bouguet's edges alone put the pedestal at 36.6 grey, above
    # one dark square in twenty (32 grey): those squares' profiles were drawn at 36.6
    mb = measure_boards(shared_data / "bouguet-calib-example", Chessboard(13, 12, 30.0))
    darkest = darkest_plateau([p.edges for p in mb.photographs])
    assert 25.0 / 255.0 < darkest < 35.0 / 255.0
    fit = fit_causes(mb.photographs, [CAUSES_BY_NAME["response_toe"], CAUSES_BY_NAME["response_shoulder"]])
    assert fit.model.black_level <= darkest + 0.5 / 255.0, fit.model.black_level * 255.0
    assert fit.model.black_level > 0.05  # still a toe: the edges ask for one
