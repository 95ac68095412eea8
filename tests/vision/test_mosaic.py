"""A colour camera's raw Bayer mosaic given as a grey image is named, where locate refuses it."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.vision.locate import locate
from doorloc.vision.mosaic import bayer_mosaic


def _mosaic(bgr: np.ndarray, pattern: str) -> np.ndarray:
    """The raw samples a sensor with the colour filter ``pattern`` (its 2 x 2 block row by row, e.g. RGGB)
    takes of ``bgr``."""
    channel = {"B": 0, "G": 1, "R": 2}
    raw = np.empty(bgr.shape[:2], bgr.dtype)
    for k, c in enumerate(pattern):
        i, j = divmod(k, 2)
        raw[i::2, j::2] = bgr[i::2, j::2, channel[c]]
    return raw


@pytest.fixture(scope="module")
def doors(thesis_cell_path):
    cell = load_cell(thesis_cell_path)
    door = DoorSize(900, 50, 2100)
    fx = Effects(color=True, read_noise_dn=1.0, full_well_e=9000.0, blur_sigma_px=0.8)
    poses = [DoorPose(3.0, -2.0, 0.7), DoorPose(7.0, 1.0, 1.5)]
    return (
        cell,
        door,
        [render_door(cell, door, p, effects=fx, seed=s).image for s, p in ((0, poses[0]), (2, poses[1]))],
    )


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_a_raw_mosaic_is_told_by_its_sites_and_nothing_else_is(doors, pattern):
    """The wood door's raw samples through each filter layout: red above green, blue below, on the
    layout's rows; the same door as grey, the public board photographs, a camera whose raw channels are
    balanced and a 16-bit mosaic's depth are no mosaic / the same mosaic."""
    _, _, (bgr, _) = doors
    m = bayer_mosaic(_mosaic(bgr, pattern))
    assert m is not None
    red_first = pattern.index("R") < 2
    red, blue = (m.first, m.second) if red_first else (m.second, m.first)
    assert red > 0.05 and blue < -0.05, m
    deep = bayer_mosaic(_mosaic(bgr.astype(np.uint16) * 257, pattern))
    assert deep is not None and deep.first == pytest.approx(m.first, abs=1e-9)
    assert bayer_mosaic(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)) is None
    balanced = bgr.astype(float) * (bgr[..., 1].mean() / bgr.reshape(-1, 3).mean(axis=0))
    assert bayer_mosaic(_mosaic(np.clip(balanced, 0, 255).astype(np.uint8), pattern)) is None
    assert bayer_mosaic(bgr) is None  # (a colour image has its channels apart)


def test_no_public_photograph_shows_a_mosaic(shared_data):
    """Real grey photographs (OpenCV's and Bouguet's boards, the latter's even and odd rows 0.3 % apart)."""
    data = shared_data
    files = sorted(data.glob("opencv-left/left*.jpg")) + sorted(data.glob("bouguet-calib-example/*.png"))
    assert len(files) >= 30
    for f in files:
        assert bayer_mosaic(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)) is None, f.name


def test_a_refused_mosaic_is_named_for_what_it_is(doors):
    """Read as grey, the mosaic's doors were refused `edge_not_straight` ("something covers the edge"); the
    refusal now names the camera's raw mode and keeps locate's own reading after it."""
    cell, door, images = doors
    for bgr in images:
        r = locate(_mosaic(bgr, "RGGB"), cell, door)
        assert not r.ok and r.error_code == "bad_image", r.error
        assert "raw Bayer mosaic" in r.error and "read as grey, locate found:" in r.error
        assert locate(bgr, cell, door).ok
