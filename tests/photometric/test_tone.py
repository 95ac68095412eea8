"""The free tone curve (``tone_1..6``): a response no closed form draws, bent in ln light at six grey levels.
The maps invert each other, files carry it, locate reads it, and the model check, which tries it after the closed
forms on sixteen rendered photographs, names it (a whole sine wave of it; half a wave is a log-log curvature)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.calib.detect import Chessboard
from doorloc.calib.io import CalibrationFile
from doorloc.photometric.catalogue import CAUSES_BY_NAME, TONE_CAUSE
from doorloc.photometric.check import check_boards
from doorloc.photometric.model import TONE_KNOTS, TONE_NAMES, PhotometricModel
from doorloc.sim.boards import Checkerboard
from doorloc.sim.photometric import random_board_views

CAMERA = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)


def _sine_tone(amplitude: float, phase: float, waves: float) -> dict[str, float]:
    return {
        n: amplitude * np.sin(2 * np.pi * waves * g + phase)
        for n, g in zip(TONE_NAMES, TONE_KNOTS, strict=True)
    }


def _tone(values) -> PhotometricModel:
    return PhotometricModel(gamma=2.0, **dict(zip(TONE_NAMES, values, strict=True)))


def test_tone_bends_ln_light_at_its_knots_and_nowhere_at_black():
    m = _tone([0.1, -0.2, 0.3, 0.0, -0.1, 0.2])
    plain = PhotometricModel(gamma=2.0)
    g = np.concatenate([TONE_KNOTS, [1 / 12, 0.25]])
    ratio = np.log(m.light_from_grey(g) / plain.light_from_grey(g))
    # at the knots the values, between them the straight line, from 0 at black
    assert ratio[:6] == pytest.approx([0.1, -0.2, 0.3, 0.0, -0.1, 0.2], abs=1e-12)
    assert ratio[6] == pytest.approx(0.05, abs=1e-12)
    assert ratio[7] == pytest.approx(-0.05, abs=1e-12)
    assert m.beyond_power_law and not m.linear_response and m.has_tone
    assert not plain.has_tone and not plain.beyond_power_law
    # what locate takes of the model carries it
    assert m.locate_parameters()["tone_3"] == 0.3


@settings(max_examples=40, deadline=None)
@given(
    st.floats(0.0, 0.15),
    st.floats(0.0, 2 * np.pi),
    st.sampled_from([0.5, 1.0]),
    st.floats(1.0, 2.4),
    st.floats(0.03, 0.97),
)
def test_maps_invert_each_other_with_a_tone(amplitude, phase, waves, gamma, grey):
    # the hidden tones of bench_boards_model: a whole sine wave over the grey scale (and half of one)
    m = PhotometricModel(gamma=gamma, **_sine_tone(amplitude, phase, waves))
    light = m.light_from_grey(np.linspace(0.0, 1.0, 4097))
    assert np.all(np.diff(light) > 0)  # never falls: every level is one light
    back = m.grey_from_light(m.light_from_grey(np.array([grey])))[0]
    assert back == pytest.approx(grey, abs=1e-3)


def test_tone_validated_and_read_from_files():
    with pytest.raises(ValueError, match="tone"):
        PhotometricModel(tone_2=4.0)
    m = _tone([0.05, 0.1, -0.1, 0.02, 0.0, -0.03])
    assert PhotometricModel.from_dict(m.to_dict()) == m
    assert CAUSES_BY_NAME["response_tone"] is TONE_CAUSE and TONE_CAUSE.parameters == TONE_NAMES


@pytest.mark.slow
def test_hidden_tone_is_named_on_sixteen_photographs(tmp_path):
    # bench_boards_model's draw of seed 35108 (named there, as 2 of its 3 seeds are; the third a toe explains
    # to 0.026 px): CI must not pass or fail by the draw
    seed = 35108
    rng = np.random.default_rng(seed)
    values = _sine_tone(float(rng.uniform(0.1, 0.15)), float(rng.uniform(0, 2 * np.pi)), 1.0)
    print(f"seed {seed}: hidden tone {values}")
    for name, img in random_board_views(
        CAMERA, Checkerboard(9, 6, 25.0), PhotometricModel(**values), 16, seed
    ):
        cv2.imwrite(str(tmp_path / name), img)
    c = check_boards(tmp_path, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
    assert "response_tone" in c.causes, (seed, c.causes)
    off = c.heldout_rms("offset")
    assert off["after"] < 0.25 * off["before"], (seed, off)
    # the curve it measures is the hidden one where the edges' levels lie (the dark squares sit near 1/12 of
    # full scale, the light ones at 0.57-0.9: the knots 4/6 .. 1 are read)
    got = np.array([c.parameters["response_tone"][n]["value"] for n in TONE_NAMES[3:]])
    assert np.allclose(got, [values[n] for n in TONE_NAMES[3:]], atol=0.05), (seed, got)
