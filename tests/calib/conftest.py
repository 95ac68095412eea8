"""Shared fixtures of the calibration tests: the real photographs and their detections (computed once)."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import pytest

DATA = Path(__file__).parents[2].parent / "shared" / "data"
OPENCV_LEFT = DATA / "opencv-left"
BOUGUET = DATA / "bouguet-calib-example"

sys.path.insert(0, str(Path(__file__).parent))  # rendered_views helper


def _views(folder: Path, pattern: str, board):
    from doorloc.calib.calibrate import View
    from doorloc.calib.detect import scan_images

    files = sorted(folder.glob(pattern))
    images = [(p.name, cv2.imread(str(p), cv2.IMREAD_GRAYSCALE), None) for p in files]
    scan = scan_images(images, board)
    return scan, [View(n, d.object_points(board), d.corners_px, d.ids) for n, d in scan.detections.items()]


@pytest.fixture(scope="session")
def opencv_left():
    if not OPENCV_LEFT.is_dir():
        pytest.fail(f"real data not found at {OPENCV_LEFT}: clone the repository with shared/ beside it")
    from doorloc.calib.detect import Chessboard

    board = Chessboard(9, 6, 25.0)
    scan, views = _views(OPENCV_LEFT, "left*.jpg", board)
    return board, scan, views


@pytest.fixture(scope="session")
def bouguet():
    if not BOUGUET.is_dir():
        pytest.fail(f"real data not found at {BOUGUET}: clone the repository with shared/ beside it")
    from doorloc.calib.detect import Chessboard

    board = Chessboard(13, 12, 30.0)
    scan, views = _views(BOUGUET, "Image*.png", board)
    return board, scan, views
