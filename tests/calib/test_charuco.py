"""ChArUco boards: partial views, calibration through `doorloc calibrate --charuco`."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from rendered_views import render_views, true_camera
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.calib.calibrate import CANDIDATES_BY_NAME
from doorloc.calib.detect import CharucoSpec
from doorloc.calib.folder import calibrate_detected, detect_views
from doorloc.calib.io import load_calibration


@pytest.fixture(scope="module")
def charuco_images():
    from doorloc.sim.boards import CharucoBoard
    from doorloc.sim.effects import Effects

    return render_views(
        true_camera(),
        CharucoBoard(9, 7, 25.0, 18.0),
        8,
        seed=4,
        effects=Effects(blur_sigma_px=0.7, read_noise_dn=1.0),
    )


def test_charuco_views_calibrate_the_known_camera(charuco_images):
    true = true_camera()
    spec = CharucoSpec(9, 7, 25.0, 18.0)
    # hide part of one board: ChArUco corners are still named by their ids
    name, im, truth = charuco_images[0]
    part = im.copy()
    x0, x1 = truth[:, 0].min(), truth[:, 0].max()
    part[:, : int(x0 + 0.4 * (x1 - x0))] = 77  # the left 40 % of the board covered
    images = [(n, i, None) for n, i, _ in charuco_images[1:]] + [(name, part, None)]
    detected = detect_views(images, spec)
    scan = detected.scan
    assert len(scan.detections) == 8
    det = scan.detections[name]
    assert 10 <= len(det.ids) < spec.n_corners
    assert np.max(np.linalg.norm(det.corners_px - truth[det.ids], axis=1)) < 0.3
    res = calibrate_detected(detected, candidates=(CANDIDATES_BY_NAME["plumb_bob"],)).result
    assert abs(res.camera.fx / true.fx - 1) < 0.002
    assert abs(res.camera.cx - true.cx) < 1.0 and abs(res.camera.cy - true.cy) < 1.0


def test_calibrate_cli_with_a_charuco_board(charuco_images, tmp_path):
    for n, im, _ in charuco_images:
        cv2.imwrite(str(tmp_path / n), im)
    out = tmp_path / "out" / "camera.yaml"
    r = CliRunner().invoke(
        app,
        [
            "calibrate",
            str(tmp_path),
            "--pattern",
            "9x7",
            "--square",
            "25",
            "--charuco",
            "--marker",
            "18",
            "--model",
            "k1k2",
            "--out",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    cam = load_calibration(out).camera
    assert abs(cam.fx / true_camera().fx - 1) < 0.003
    # a ChArUco board's squares are broken by its markers: no optics measured on them, nothing said of them
    assert load_calibration(out).photometric_model is None and "camera optics" not in r.output
