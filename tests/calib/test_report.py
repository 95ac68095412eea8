"""The calibration report: coverage, warnings a person can act on, JSON + PNG written atomically."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from conftest import OPENCV_LEFT
from doorloc.calib.calibrate import CANDIDATES_BY_NAME
from doorloc.calib.folder import calibrate_detected
from doorloc.calib.report import (
    calibration_warnings,
    coverage_grid,
    render_report_png,
    report_dict,
    write_report,
)


@pytest.fixture(scope="module")
def left(opencv_left_detected):
    d = opencv_left_detected
    return d.board, d.scan, calibrate_detected(d, candidates=(CANDIDATES_BY_NAME["plumb_bob"],)).result


def test_coverage_counts_every_kept_corner(left):
    _, _, res = left
    grid = coverage_grid(res)
    assert grid.shape == (6, 8)
    assert grid.sum() == sum(v.n for v in res.views)
    assert grid[:, 0].sum() < grid[:, 3].sum()  # the left edge of these photographs is barely covered
    doc = report_dict(res)
    assert [0, 0] in doc["coverage"]["thin_cells"] and [3, 2] not in doc["coverage"]["thin_cells"]
    assert (
        doc["coverage"]["board_tilt_deg"]["about_x"][0]
        < -20
        < 20
        < doc["coverage"]["board_tilt_deg"]["about_x"][1]
    )
    sig = doc["projection_uncertainty_px"]
    assert sig["max_observed_aligned"] < sig["max_observed_aligned_95"]


def test_warnings_name_what_to_do(left):
    _, scan, res = left
    warnings = calibration_warnings(res, scan)
    text = "\n".join(warnings)
    assert "reached only" in text and "add views with the board near the image corners" in text
    assert "top-left" in text  # the uncovered part of the image is named
    # thinly covered parts are named too (not the empty ones again)
    thin = next(w for w in warnings if w.startswith("few board corners"))
    assert "bottom-right" in thin and "top-left" not in thin
    assert not any("tilted about" in w for w in warnings)  # these boards were tilted +-25-40 deg both ways


def test_boards_never_tilted_are_warned_about(left):
    import dataclasses

    import numpy as np

    _, scan, res = left
    flat = dataclasses.replace(
        res, fit=dataclasses.replace(res.fit, rvecs=[np.zeros(3) for _ in res.fit.rvecs])
    )
    text = "\n".join(calibration_warnings(flat, scan))
    assert "tilted about the camera's horizontal axis only over 0 deg" in text
    assert "tilted about the camera's vertical axis only over 0 deg" in text


def test_report_json_and_png(left, tmp_path):
    board, scan, res = left
    doc = report_dict(res, scan, board)
    for key in (
        "camera_matrix",
        "dist_coeffs",
        "rms_px",
        "std_1sigma",
        "std_jackknife",
        "model_selection",
        "views",
        "rejected",
        "coverage",
        "observed_radius_px",
        "projection_uncertainty_px",
        "validity",
        "warnings",
    ):
        assert key in doc
    assert doc["board"] == {"type": "Chessboard", "cols": 9, "rows": 6, "square_mm": 25.0}
    assert doc["validity"]["observed_radius_px"] == pytest.approx(res.camera.observed_radius_px)
    bg = cv2.imread(str(OPENCV_LEFT / "left01.jpg"))
    jpath, ppath = write_report(tmp_path / "rep", res, scan, board, bg)
    assert json.loads(jpath.read_text())["model_selection"]["candidates"][0]["name"] == "plumb_bob"
    png = cv2.imread(str(ppath))
    assert png.shape[0] == 480 and png.shape[1] > 640
    assert sorted(p.name for p in (tmp_path / "rep").iterdir()) == [
        "calibration_report.json",
        "calibration_report.png",
    ]
    green = (png[:, :640, 1] > 200) & (png[:, :640, 0] < 60) & (png[:, :640, 2] < 60)
    assert green.sum() > 200  # the observed-radius circle is drawn
    # a 16-bit photograph (a 12-bit camera's, levels to 4095) is the same picture, not its levels cast to 8
    # bits (which wrapped them round 256)
    grey = cv2.cvtColor(bg, cv2.COLOR_BGR2GRAY)
    deep = np.rint(grey * (4095 / 255)).astype(np.uint16)
    pictures = [render_report_png(res, b)[:, :640].astype(float) for b in (grey, deep)]
    assert np.abs(pictures[0] - pictures[1]).mean() < 2.0, np.abs(pictures[0] - pictures[1]).mean()
