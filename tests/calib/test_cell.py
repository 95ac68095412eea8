"""One-shot cell calibration: a rendered board on the hinge-face plane of the thesis cell."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.app.errors import EXIT_REFUSED, EXIT_USAGE
from doorloc.calib.cell import CellCalibrationError, board_points_in_cell, calibrate_cell_extrinsics
from doorloc.calib.detect import Chessboard, detect_chessboard
from doorloc.cell import load_cell

FIXTURE = Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml"
ORIGIN = (-50.0, 0.0, 90.0)  # board corner 0 (seen top-left) on the hinge face Y = 0, mm
runner = CliRunner()


@pytest.fixture(scope="module")
def scene():
    """The thesis cell, and its camera's view of a 9x6 board (20 mm squares) lying on the hinge face."""
    from doorloc.calib.camera import Extrinsics
    from doorloc.sim.boards import Checkerboard, render_board
    from doorloc.sim.effects import Effects

    cell = load_cell(FIXTURE)
    ext = cell.extrinsics
    bx, by = np.array([1.0, 0, 0]), np.array([0, 0, -1.0])
    R_board = ext.rotation @ np.stack([bx, by, np.cross(bx, by)], axis=1)
    t_board = ext.cell_to_camera(np.array(ORIGIN)[None])[0]
    board_pose = Extrinsics.from_rotation(R_board, t_board)
    rb = render_board(
        cell.camera,
        Checkerboard(9, 6, 20.0),
        board_pose.rvec,
        board_pose.tvec_mm,
        seed=3,
        effects=Effects(blur_sigma_px=0.8, read_noise_dn=1.0),
    )
    return cell, rb


def test_board_points_follow_the_given_axes():
    p = board_points_in_cell(np.array([[20.0, 40.0, 0.0]]), ORIGIN)
    np.testing.assert_allclose(p, [[-30.0, 0.0, 50.0]])
    with pytest.raises(CellCalibrationError, match="perpendicular"):
        board_points_in_cell(np.zeros((1, 3)), ORIGIN, (1, 0, 0), (1, 1, 0))


def test_extrinsics_and_scale_are_recovered_from_one_view(scene):
    cell, rb = scene
    board = Chessboard(9, 6, 20.0)
    det = detect_chessboard(rb.image, board)
    assert det is not None
    np.testing.assert_allclose(det.corners_px, rb.corners_px, atol=0.2)  # canonical order = board order here
    pts = board_points_in_cell(det.object_points(board), ORIGIN)
    res = calibrate_cell_extrinsics(cell.camera, pts, det.corners_px, 0.0)
    true = cell.extrinsics
    assert res.rms_px < 0.1
    np.testing.assert_allclose(res.extrinsics.tvec_mm, true.tvec_mm, atol=0.3)
    dR = res.extrinsics.rotation @ true.rotation.T
    assert np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1))) < 0.02
    truth_scale = cell.posed_camera.scale_mm_per_px(np.zeros(3))
    assert res.scale_mm_per_px == pytest.approx(truth_scale, rel=2e-3)
    assert res.scale_mm_per_px == pytest.approx(0.206, abs=0.003)
    err = np.linalg.norm(res.reference_corner_px - cell.posed_camera.project_cell(np.zeros((1, 3)))[0])
    assert 0 < res.reference_corner_sigma_px < 0.1
    assert err < 5 * res.reference_corner_sigma_px  # the reported uncertainty covers the actual error


def test_calibrate_cell_cli_writes_the_extrinsics(scene, tmp_path):
    cell, rb = scene
    image = tmp_path / "board.png"
    cv2.imwrite(str(image), rb.image)
    start = tmp_path / "cell.yaml"
    text = FIXTURE.read_text().replace("tvec_mm: [-30.0, 40.0, 350.0]", "tvec_mm: [0.0, 0.0, 300.0]")
    start.write_text(text)
    out = tmp_path / "cell_calibrated.yaml"
    r = runner.invoke(
        app,
        [
            "calibrate-cell",
            str(image),
            "--cell",
            str(start),
            "--pattern",
            "9x6",
            "--square",
            "20",
            "--board-origin",
            *map(str, ORIGIN),
            "--out",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    assert "mm/px" in r.output
    new = load_cell(out)
    np.testing.assert_allclose(new.extrinsics.tvec_mm, cell.extrinsics.tvec_mm, atol=0.3)
    np.testing.assert_allclose(new.camera.camera_matrix, cell.camera.camera_matrix)
    import yaml

    doc = yaml.safe_load(out.read_text())
    assert doc["provenance"]["cell_calibration"]["rms_px"] < 0.1
    assert doc["provenance"]["cell_calibration"]["scale_mm_per_px"] == pytest.approx(0.206, abs=0.003)


def test_calibrate_cell_refuses_without_a_board_and_writes_nothing(tmp_path):
    image = tmp_path / "blank.png"
    cv2.imwrite(str(image), np.full((1080, 1920), 100, np.uint8))
    out = tmp_path / "out.yaml"
    shutil.copy(FIXTURE, tmp_path / "cell.yaml")
    args = [
        "calibrate-cell",
        str(image),
        "--cell",
        str(tmp_path / "cell.yaml"),
        "--pattern",
        "9x6",
        "--square",
        "20",
        "--board-origin",
        "0",
        "0",
        "0",
        "--out",
        str(out),
    ]
    r = runner.invoke(app, args)
    assert r.exit_code == EXIT_REFUSED and "no board" in r.output
    assert not out.exists()
    cv2.imwrite(str(image), np.full((480, 640), 100, np.uint8))
    r = runner.invoke(app, args)
    assert r.exit_code == EXIT_USAGE and "640x480" in r.output
    assert not out.exists()
