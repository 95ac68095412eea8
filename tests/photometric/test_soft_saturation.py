"""A soft saturation: the response's shoulder approaches its own white level below full scale. The response
maps invert each other below it and never store above it, the renderer makes such photographs, and the model
check names the cause when it is hidden in rendered boards (strength drawn at random, seed printed) and
answers [] on a control."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.calib.detect import Chessboard
from doorloc.calib.io import CalibrationFile
from doorloc.photometric.check import check_boards
from doorloc.photometric.clipping import white_starts
from doorloc.photometric.model import PhotometricModel
from doorloc.sim.boards import Checkerboard
from doorloc.sim.photometric import CameraRendering, random_board_views, render_photographed_board

CAMERA = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(0.6, 1.0),
    st.floats(0.05, 0.4),
    st.floats(0.5, 2.5),
    st.floats(0.0, 0.1),
    st.floats(0.0, 1.0),
    st.floats(1.0, 8.0),
)
def test_response_saturates_smoothly_at_the_white_level(white, span, gamma, black, q, order):
    m = PhotometricModel(
        gamma=gamma, black_level=black, shoulder=white - span, white_level=white, shoulder_order=order
    )
    light = np.linspace(0.0, 50.0, 2001)
    g = m.grey_from_light(light)
    # never above the white level (to the table's step), never falling, and the last stored levels come
    # within 0.01 of it
    assert g.max() <= white + 1.0 / 4096
    assert np.all(np.diff(g) >= -1e-12)
    assert g[-1] > white - 0.01
    # below the white level the two maps invert each other
    grey = black + 0.02 + q * (0.98 * white - black - 0.02)
    back = m.grey_from_light(m.light_from_grey(np.array([grey])))[0]
    assert back == pytest.approx(grey, abs=2e-3)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.5, 0.8), st.floats(0.05, 0.2), st.floats(1.0, 8.0), st.floats(0.0, 1.0))
def test_the_shoulders_order_sets_where_its_roll_off_ends(knee, headroom, order, u):
    """``g = W - (W - k) (1 - (x - k) / (p (W - k)))^p`` above the knee ``k``: the power law's slope kept at the
    knee, the white level ``W`` reached at the light ``k + p (W - k)``; order 2 the quadratic it always was."""
    white = knee + headroom
    m = PhotometricModel(shoulder=knee, white_level=white, shoulder_order=order)
    x = knee + u * order * headroom  # a light inside the roll-off
    expected = white - headroom * (1.0 - u) ** order
    assert m.grey_from_light(np.array([x]))[0] == pytest.approx(expected, abs=1e-3)
    end = m.light_from_grey(np.array([white]))[0]
    assert end == pytest.approx(knee + order * headroom, rel=1e-9)
    just_above = m.light_from_grey(np.array([knee + 1e-6]))[0]
    assert just_above - knee == pytest.approx(1e-6, rel=1e-3)  # slope 1 at the knee
    quadratic = PhotometricModel(shoulder=knee, white_level=white)
    grey = knee + u * headroom
    assert quadratic.light_from_grey(np.array([grey]))[0] == pytest.approx(
        knee + 2.0 * headroom * (1.0 - np.sqrt(1.0 - u)), abs=1e-12
    )


def test_white_level_validated_and_read_from_files():
    with pytest.raises(ValueError, match="white_level"):
        PhotometricModel(white_level=1.2)
    with pytest.raises(ValueError, match="white_level"):
        PhotometricModel(white_level=0.3, black_level=0.3)
    with pytest.raises(ValueError, match="shoulder_order"):
        PhotometricModel(shoulder=0.7, white_level=0.9, shoulder_order=0.5)
    m = PhotometricModel(shoulder=0.7, white_level=0.9, shoulder_order=3.0)
    assert PhotometricModel.from_dict(m.to_dict()) == m
    assert m.locate_parameters()["shoulder_order"] == 3.0  # a cell saved with the camera keeps it
    assert not m.linear_response and PhotometricModel().linear_response


@pytest.mark.parametrize("white, knee", [(0.8, 0.6), (0.9, 0.65)])
def test_renderer_rolls_off_to_the_white_level_at_a_finite_light(white, knee):
    rvec = np.array([0.1, -0.2, 0.05])
    tvec = -np.array([100.0, 62.5, 0.0]) + np.array([0.0, 0.0, 450.0])
    model = PhotometricModel(shoulder=knee, white_level=white)

    def shot(m: PhotometricModel, exposure: float) -> np.ndarray:
        look = CameraRendering(0.8, exposure, 0.5)
        return render_photographed_board(CAMERA, Checkerboard(9, 6, 25.0), rvec, tvec, m, look, seed=5).image

    light = shot(PhotometricModel(), 1.05) > 200  # the light squares (light 0.9 x the exposure)
    top = int(np.rint(white * 255))
    full_well = knee + 2.0 * (white - knee)  # the light the shoulder reaches the white level at
    inside = [shot(model, e) for e in (0.8 * full_well / 0.9, 0.9 * full_well / 0.9)]
    levels = [float(np.median(im[light])) for im in inside]
    # in the shoulder: the roll-off's levels (compressed below the linear response, above the knee), and
    # more light stores higher
    for x, level in zip((0.8 * full_well, 0.9 * full_well), levels, strict=True):
        expected = 255 * (white - (white - knee) * (1.0 - (x - knee) / (2.0 * (white - knee))) ** 2)
        assert abs(level - expected) <= 1.5, (x, level, expected)
        assert knee * 255 < level < min(x, white) * 255
    assert levels[0] < levels[1] < top
    # beyond it every light is stored at the white level, never above it
    beyond = shot(model, 1.2 * full_well / 0.9)
    assert beyond.max() <= top and np.median(beyond[light]) == top
    assert max(im.max() for im in inside) <= top


def test_fit_starts_place_the_white_level_just_above_the_plateaus():
    rng = np.random.default_rng(11)
    brights = rng.uniform(150.0, 200.0, 500)
    starts = white_starts(brights)
    whites = {w for _, w in starts}
    assert min(whites) > 199.0 / 255.0 and max(whites) < 200.0 / 255.0 + 0.06
    assert all(k < w for k, w in starts)
    # plateaus at full scale: the white level is full scale, the shoulder alone is fitted
    assert {w for _, w in white_starts(np.full(50, 255.0))} == {1.0}


def _check(folder: Path, model: PhotometricModel, seed: int):
    folder.mkdir()
    for name, img in random_board_views(CAMERA, Checkerboard(9, 6, 25.0), model, 8, seed):
        cv2.imwrite(str(folder / name), img)
    return check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))


@pytest.mark.slow
def test_hidden_soft_saturation_is_named(tmp_path):
    # a fixed default draw so that CI does not pass or fail by the draw; DOORLOC_TEST_SEED tries another
    seed = int(os.environ.get("DOORLOC_TEST_SEED", 35009))
    rng = np.random.default_rng(seed)
    white = rng.uniform(0.75, 0.9)
    values = {"white_level": white, "shoulder": white - rng.uniform(0.15, 0.3)}
    # (drawn as bench_boards_model.py draws it: 3.92 at the default seed, a roll-off over twice the light a
    # quadratic's takes; held at 2 the check left 0.019 px of the 0.177, its order freed 0.008)
    values["shoulder_order"] = rng.uniform(1.5, 4.0)
    print(f"seed {seed}: hidden soft_saturation {values}")
    c = _check(tmp_path / "boards", PhotometricModel(**values), seed)
    assert "soft_saturation" in c.causes, (seed, c.causes)
    p = c.parameters["soft_saturation"]
    assert abs(p["white_level"]["value"] - white) < max(0.02, 3 * p["white_level"]["sigma"]), (seed, p)
    if abs(values["shoulder_order"] - 2.0) > 1.0:  # an order the photographs can tell from the quadratic's
        order = p["shoulder_order"]
        assert abs(order["value"] - values["shoulder_order"]) < max(0.5, 3 * order["sigma"]), (seed, p)
    off = c.heldout_rms("offset")
    assert off["after"] < 0.5 * off["before"], (seed, off)


@pytest.mark.slow
def test_control_with_soft_saturation_in_the_catalogue_answers_nothing(tmp_path):
    seed = int(os.environ.get("DOORLOC_TEST_SEED", 35050))
    print(f"seed {seed}: control")
    c = _check(tmp_path / "boards", PhotometricModel(), seed)
    assert c.causes == [], (seed, c.causes)
