"""Shared fixtures of the calibration tests: the real photographs and their detections (computed once)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

DATA = Path(__file__).parents[2].parent / "shared" / "data"
OPENCV_LEFT = DATA / "opencv-left"
BOUGUET = DATA / "bouguet-calib-example"

sys.path.insert(0, str(Path(__file__).parent))  # rendered_views helper


def _detected(folder: Path, glob: str, board):
    """The board views of a real data set, found as ``doorloc calibrate`` finds them."""
    from doorloc.calib.folder import detect_views, read_folder

    if not folder.is_dir():
        pytest.fail(f"real data not found at {folder}: clone the repository with shared/ beside it")
    return detect_views(read_folder(folder, glob), board)


@pytest.fixture(scope="session")
def opencv_left_detected():
    from doorloc.calib.detect import Chessboard

    return _detected(OPENCV_LEFT, "left*.jpg", Chessboard(9, 6, 25.0))


@pytest.fixture(scope="session")
def bouguet_detected():
    from doorloc.calib.detect import Chessboard

    return _detected(BOUGUET, "Image*.png", Chessboard(13, 12, 30.0))


@pytest.fixture(scope="session")
def opencv_left(opencv_left_detected):
    d = opencv_left_detected
    return d.board, d.scan, d.views


@pytest.fixture(scope="session")
def bouguet(bouguet_detected):
    d = bouguet_detected
    return d.board, d.scan, d.views
