"""`doorloc cell init` and the guide's first hour (docs/guide.md): calibration -> starting cell -> calibrate-cell -> locate."""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.app.errors import EXIT_USAGE
from doorloc.calib.camera import Extrinsics
from doorloc.calib.cell_init import REFERENCE_MOUNT_RVEC, StartingCell, starting_cell_document
from doorloc.cell import CellFileError, load_cell, parse_cell
from doorloc.vision.locate import locate

ROOT = Path(__file__).parents[2]
BOARDS = ROOT / "fixtures" / "boards"
CAMERA = BOARDS / "camera_thesis.yaml"
DISTRACTORS = ROOT / "fixtures" / "rendered" / "distractors"
runner = CliRunner()


def _run(*args: object):
    return runner.invoke(app, [str(a) for a in args])


def test_first_hour_from_a_calibration_to_a_located_door(tmp_path):
    """The guide's walk-through (docs/guide.md) with the bundled thesis camera and board image."""
    cell_file = tmp_path / "cell.yaml"
    r = _run("cell", "init", "--calibration", CAMERA, "--out", cell_file)
    assert r.exit_code == 0, r.output
    assert "calibrate-cell" in r.output
    r = _run(
        "calibrate-cell",
        BOARDS / "cell_board.png",
        "--cell",
        cell_file,
        "--pattern",
        "9x6",
        "--square",
        "20",
        "--board-origin",
        "-50",
        "0",
        "90",
        "--out",
        cell_file,
    )
    assert r.exit_code == 0, r.output
    cell = load_cell(cell_file)
    thesis = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
    # the board image was rendered from the thesis cell's placement: calibrate-cell must find it again
    assert np.allclose(cell.extrinsics.camera_centre_cell, thesis.extrinsics.camera_centre_cell, atol=0.5)
    assert np.allclose(cell.extrinsics.rotation, thesis.extrinsics.rotation, atol=1e-3)
    # and the calibrated cell locates a rendered door where its truth row says
    with (DISTRACTORS / "truth.csv").open(newline="") as f:
        truth = next(row for row in csv.DictReader(f) if row["image"] == "img_0003.png")
    image = cv2.imread(str(DISTRACTORS / "img_0003.png"), cv2.IMREAD_UNCHANGED)
    res = locate(image, cell)
    assert res.ok, res.error
    assert res.x_mm == pytest.approx(float(truth["x_mm"]), abs=0.05)
    assert res.z_mm == pytest.approx(float(truth["z_mm"]), abs=0.05)
    assert res.yaw_deg == pytest.approx(float(truth["yaw_deg"]), abs=0.01)


def test_cell_init_stores_the_calibration_relative_to_the_cell_file(tmp_path):
    cal = tmp_path / "cam" / "camera.yaml"
    cal.parent.mkdir()
    cal.write_bytes(CAMERA.read_bytes())
    r = _run("cell", "init", "--calibration", cal, "--out", tmp_path / "cell.yaml", "--door-width", "1000")
    assert r.exit_code == 0, r.output
    text = (tmp_path / "cell.yaml").read_text()
    assert "calibration: cam/camera.yaml" in text
    cell = load_cell(tmp_path / "cell.yaml")
    assert cell.camera.image_size == (1920, 1080)
    assert cell.default_door.width_mm == 1000.0


def test_cell_files_name_a_calibration_outside_their_folder_relatively(tmp_path):
    """cell init and calibrate-cell: a cell folder checked out elsewhere still finds its calibration."""
    cal = tmp_path / "calib" / "camera.yaml"
    cal.parent.mkdir()
    cal.write_bytes(CAMERA.read_bytes())
    cell_file = tmp_path / "cells" / "a" / "cell.yaml"
    cell_file.parent.mkdir(parents=True)
    r = _run("cell", "init", "--calibration", cal, "--out", cell_file)
    assert r.exit_code == 0, r.output
    assert "calibration: ../../calib/camera.yaml" in cell_file.read_text()
    placed = tmp_path / "cells" / "placed.yaml"
    args = ("--pattern", "9x6", "--square", "20", "--board-origin", "-50", "0", "90", "--out", placed)
    r = _run("calibrate-cell", BOARDS / "cell_board.png", "--cell", cell_file, *args)
    assert r.exit_code == 0, r.output
    assert "calibration: ../calib/camera.yaml" in placed.read_text()  # rebased to where it was written
    assert str(tmp_path) not in placed.read_text().split("provenance:")[0]
    assert load_cell(placed).camera.image_size == (1920, 1080)


def test_cell_init_never_replaces_a_cell_file_unless_forced(tmp_path):
    out = tmp_path / "cell.yaml"
    out.write_text("calibrated: keep me\n")
    r = _run("cell", "init", "--calibration", CAMERA, "--out", out)
    assert r.exit_code == EXIT_USAGE
    assert "already exists" in r.output and "--force" in r.output
    assert out.read_text() == "calibrated: keep me\n"
    r = _run("cell", "init", "--calibration", CAMERA, "--out", out, "--force")
    assert r.exit_code == 0, r.output
    assert load_cell(out).camera.image_size == (1920, 1080)


@pytest.mark.parametrize("calibration", ["missing.yaml", "fixtures/cell_thesis.yaml"])
def test_cell_init_refuses_what_is_not_a_calibration_and_writes_nothing(tmp_path, calibration):
    out = tmp_path / "cell.yaml"
    r = _run("cell", "init", "--calibration", ROOT / calibration, "--out", out)
    assert r.exit_code == EXIT_USAGE, r.output
    assert "nothing written" in r.output
    assert "Traceback" not in r.output
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_cell_init_refuses_an_impossible_door(tmp_path):
    r = _run(
        "cell", "init", "--calibration", CAMERA, "--out", tmp_path / "cell.yaml", "--door-thickness", "-5"
    )
    assert r.exit_code == EXIT_USAGE
    assert "thickness" in r.output and not (tmp_path / "cell.yaml").exists()


@settings(deadline=None)  # each example reads the calibration file: no wall-clock limit in a test
@given(st.tuples(*[st.floats(-2000, 2000, allow_nan=False)] * 3))
def test_the_starting_placement_puts_the_camera_centre_where_asked(centre):
    doc = starting_cell_document(CAMERA, ROOT / "cell.yaml", StartingCell(camera_centre_mm=centre))
    ext = Extrinsics(doc["camera"]["extrinsics"]["rvec"], doc["camera"]["extrinsics"]["tvec_mm"])
    assert np.allclose(ext.camera_centre_cell, centre, atol=1e-6)
    # reference mount: optical axis along cell +Y, image-right +X, image-up +Z (image y runs down)
    assert np.allclose(ext.rotation @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    assert np.allclose(ext.rotation @ [1, 0, 0], [1, 0, 0], atol=1e-12)
    assert np.allclose(ext.rotation @ [0, 0, 1], [0, -1, 0], atol=1e-12)
    assert doc["camera"]["extrinsics"]["rvec"] == list(REFERENCE_MOUNT_RVEC)


def test_starting_cell_document_raises_a_cell_file_error_for_a_bad_calibration(tmp_path):
    bad = tmp_path / "camera.yaml"
    bad.write_text("%YAML:1.0\n---\nimage_width: 10\n")
    with pytest.raises(CellFileError, match="calibration"):
        starting_cell_document(bad, tmp_path / "cell.yaml")


def test_the_starting_cell_shows_every_section_a_person_may_edit(tmp_path):
    doc = starting_cell_document(CAMERA, tmp_path / "cell.yaml", StartingCell(response_gamma=2.2))
    assert set(doc) == {"camera", "fixture", "envelope", "door"}
    assert doc["camera"]["response_gamma"] == 2.2
    assert doc["door"]["arris_profile"] == "chamfer"
    with pytest.raises(CellFileError, match="response_gamma"):
        starting_cell_document(CAMERA, tmp_path / "cell.yaml", StartingCell(response_gamma=50.0))


def test_the_starting_cell_takes_the_response_the_calibration_measured(tmp_path):
    """doorloc calibrate measured the response on the photographs: cell init writes it, with the doubt its
    sigma allows, where a person sees and can edit both; without a measurement the linear default."""
    from doorloc.calib.io import load_calibration, save_calibration

    cal = load_calibration(CAMERA)
    save_calibration(replace(cal, response_gamma=2.15, response_gamma_sigma=0.12), tmp_path / "camera.yaml")
    doc = starting_cell_document(tmp_path / "camera.yaml", tmp_path / "cell.yaml")
    assert doc["camera"]["response_gamma"] == 2.15 and doc["camera"]["response_gamma_sigma"] == 0.12
    assert "locate" not in doc  # the doubt follows from the sigma, so editing the sigma moves it
    cell = parse_cell(doc, tmp_path, "cell.yaml")
    assert cell.locate.response_unmeasured_factor == pytest.approx(1.0 + 0.24 / 2.15, abs=1e-4)
    plain = starting_cell_document(CAMERA, tmp_path / "cell.yaml")
    assert plain["camera"]["response_gamma"] == 1.0 and "locate" not in plain
