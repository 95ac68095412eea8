"""`doorloc calibrate` and `doorloc validity` end to end: good input, bad input, exit codes, no partial files."""

from __future__ import annotations

import importlib
import json
import shutil

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import OPENCV_LEFT
from doorloc.app.cli import app
from doorloc.app.errors import EXIT_FAILED, EXIT_REFUSED, EXIT_USAGE
from doorloc.calib.io import load_calibration
from doorloc.cell import load_cell
from doorloc.photometric.model import PhotometricModel

runner = CliRunner()

THESIS_K = [[1678.35, 0, 946.41], [0, 1727.22, 510.71], [0, 0, 1]]
THESIS_DIST = [0.0206, 10.4073, 0.0, 0.0, -115.4536]


@pytest.fixture(scope="module")
def messy_dir(tmp_path_factory):
    """The 13 real photographs plus an unreadable file, a blank image and one of another size."""
    if not OPENCV_LEFT.is_dir():
        pytest.fail("real data missing: clone the repository with shared/ beside it")
    d = tmp_path_factory.mktemp("messy")
    for p in OPENCV_LEFT.glob("left*.jpg"):
        shutil.copy(p, d / p.name)
    (d / "broken.jpg").write_bytes(b"\xff\xd8 this is not a jpeg")
    cv2.imwrite(str(d / "blank.png"), np.full((480, 640), 128, np.uint8))
    small = cv2.resize(cv2.imread(str(OPENCV_LEFT / "left01.jpg")), (320, 240))
    cv2.imwrite(str(d / "small.png"), small)
    (d / "notes.txt").write_text("not an image, ignored by suffix")
    return d


def test_calibrate_uses_the_good_views_and_says_why_others_were_skipped(messy_dir, tmp_path):
    out = tmp_path / "camera.yaml"
    rep = tmp_path / "report"
    r = runner.invoke(
        app,
        [
            "calibrate",
            str(messy_dir),
            "--pattern",
            "9x6",
            "--square",
            "25",
            "--out",
            str(out),
            "--report",
            str(rep),
            "--no-optics",
        ],
    )
    assert r.exit_code == 0, r.output
    assert "skipped broken.jpg" in r.output and "decode" in r.output
    assert "skipped blank.png: no 9x6 chessboard" in r.output
    assert "skipped small.png: image is 320x240" in r.output
    cal = load_calibration(out)
    assert cal.camera.image_size == (640, 480)
    assert abs(cal.camera.fx / 535.916 - 1) < 0.01
    assert cal.avg_reprojection_error <= 0.393
    assert len(cal.per_view_reprojection_errors) == 13
    assert 250 < cal.camera.observed_radius_px < 330
    # the intrinsics' covariance travels with the file, for locate's uncertainty
    assert cal.covariance is not None and cal.covariance.shape == (len(cal.covariance_names),) * 2
    names = set(cal.covariance_names)  # "f" alone when the chosen model fixes the aspect ratio
    assert (
        {"cx", "cy"} <= names
        and ({"fx", "fy"} <= names or "f" in names)
        and (cal.covariance.diagonal() > 0).all()
    )
    # the camera response from the same photographs: these JPEGs scatter (0.7-3.9 one by one), and the
    # sigma says so (each image's own standard error, about 0.1 over sqrt(13), would claim 0.03)
    assert cal.response_gamma is not None and cal.response_gamma_sigma is not None
    assert 1.0 < cal.response_gamma < 3.0 and cal.response_gamma_sigma > 0.2
    assert f"camera.response_gamma: {cal.response_gamma:.2f}" in r.output
    # and what it leaves of the optics, with the command that measures them on the same photographs
    assert "camera optics: not measured" in r.output and "locate.optics_edge_sigma_px" in r.output
    assert "run this command again without --no-optics" in r.output
    assert load_calibration(out).photometric_model is None
    assert f"check-model --boards {messy_dir} --pattern 9x6 --square 25 --calibration {out}" in r.output
    doc = json.loads((rep / "calibration_report.json").read_text())
    assert {s["image"] for s in doc["skipped_images"]} == {"broken.jpg", "blank.png", "small.png"}
    assert len(doc["views"]) == 13 and sum(c["chosen"] for c in doc["model_selection"]["candidates"]) == 1
    assert any("reached only" in w for w in doc["warnings"])  # the image corners were never observed
    png = cv2.imread(str(rep / "calibration_report.png"))
    assert png is not None and png.shape[0] == 480


def test_ros_format_round_trips(messy_dir, tmp_path):
    few = tmp_path / "few"
    few.mkdir()
    for name in ("left01.jpg", "left02.jpg", "left03.jpg", "left04.jpg", "left06.jpg", "left07.jpg"):
        shutil.copy(messy_dir / name, few / name)
    out = tmp_path / "camera_ros.yaml"
    r = runner.invoke(
        app,
        [
            "calibrate",
            str(few),
            "--pattern",
            "9x6",
            "--square",
            "25",
            "--out",
            str(out),
            "--format",
            "ros",
            "--model",
            "plumb_bob",
            "--no-optics",
        ],
    )
    assert r.exit_code == 0, r.output
    text = out.read_text()
    assert "distortion_model: plumb_bob" in text and "projection_matrix" in text
    assert load_calibration(out).camera.observed_radius_px > 0


def test_too_few_views_fails_and_leaves_the_old_file_alone(messy_dir, tmp_path):
    few = tmp_path / "few"
    few.mkdir()
    for name in ("left01.jpg", "left02.jpg", "blank.png", "broken.jpg"):
        shutil.copy(messy_dir / name, few / name)
    out = tmp_path / "camera.yaml"
    out.write_text("previous calibration\n")
    r = runner.invoke(app, ["calibrate", str(few), "--pattern", "9x6", "--square", "25", "--out", str(out)])
    assert r.exit_code == EXIT_FAILED
    assert "only 2 of 4 images show the board" in r.output and "nothing written" in r.output
    assert out.read_text() == "previous calibration\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camera.yaml", "few"]  # no temporary files left


@pytest.mark.parametrize(
    "args, message",
    [
        (["--pattern", "9by6", "--square", "25"], "--pattern must look like 9x6"),
        (["--pattern", "9x6", "--square", "25", "--format", "xml"], "--format must be opencv or ros"),
        (["--pattern", "9x6", "--square", "25", "--model", "fisheye"], "--model must be auto or one of"),
        (["--pattern", "9x6", "--square", "-1"], "square size must be positive"),
        (["--pattern", "7x5", "--square", "30", "--charuco"], "needs --marker"),
        (
            ["--pattern", "7x5", "--square", "30", "--charuco", "--marker", "20", "--optics"],
            "--optics reads a chessboard's square edges",
        ),
    ],
)
def test_bad_arguments_exit_2_with_a_sentence(messy_dir, tmp_path, args, message):
    out = tmp_path / "camera.yaml"
    r = runner.invoke(app, ["calibrate", str(messy_dir), *args, "--out", str(out)])
    assert r.exit_code == EXIT_USAGE, r.output
    assert message in r.output
    assert not out.exists()


def test_missing_or_empty_folder_exits_2(tmp_path):
    out = tmp_path / "camera.yaml"
    r = runner.invoke(
        app, ["calibrate", str(tmp_path / "nope"), "--pattern", "9x6", "--square", "25", "--out", str(out)]
    )
    assert r.exit_code == EXIT_USAGE and "is not a folder" in r.output
    (tmp_path / "empty").mkdir()
    r = runner.invoke(
        app, ["calibrate", str(tmp_path / "empty"), "--pattern", "9x6", "--square", "25", "--out", str(out)]
    )
    assert r.exit_code == EXIT_USAGE and "no image files" in r.output
    assert not out.exists()


def test_thesis_coefficients_are_flagged_unusable_beyond_the_fold(tmp_path):
    cal = tmp_path / "thesis_camera.yaml"
    cal.write_text(
        f"image_width: 1920\nimage_height: 1080\ncamera_matrix: {THESIS_K}\n"
        f"distortion_coefficients: {THESIS_DIST}\n"
    )
    r = runner.invoke(app, ["validity", str(cal)])
    assert r.exit_code == EXIT_REFUSED
    assert "fold-over radius: 560" in r.output
    assert "UNUSABLE beyond 560 px" in r.output
    assert "NOT undistortable" in r.output
    r = runner.invoke(app, ["validity", str(cal), "--json"])
    doc = json.loads(r.output[: r.output.rindex("}") + 1])
    assert r.exit_code == EXIT_REFUSED
    assert doc["corners_inside_fold"] is False and round(doc["fold_radius_px"]) == 560
    assert not any(c["undistortable"] for c in doc["corner_report"])  # no image corner has a ray


def test_validity_reads_cell_files(tmp_path):
    from pathlib import Path

    fixture = Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml"
    r = runner.invoke(app, ["validity", str(fixture)])
    assert r.exit_code == 0 and "fold-over radius: none" in r.output
    text = fixture.read_text().replace(
        "dist_coeffs: [0.0, 0.0, 0.0, 0.0, 0.0]", f"dist_coeffs: {THESIS_DIST}"
    )
    cell = tmp_path / "cell.yaml"
    cell.write_text(text)
    r = runner.invoke(app, ["validity", str(cell)])
    assert r.exit_code == EXIT_REFUSED and "UNUSABLE beyond 560 px" in r.output
    r = runner.invoke(app, ["validity", str(tmp_path / "missing.yaml")])
    assert r.exit_code == EXIT_USAGE and "cannot read" in r.output


def test_a_wrong_pattern_says_which_board_the_photographs_show(messy_dir, tmp_path):
    few = tmp_path / "few"
    few.mkdir()
    for name in ("left01.jpg", "left02.jpg", "left03.jpg", "left04.jpg"):
        shutil.copy(messy_dir / name, few / name)
    out = tmp_path / "camera.yaml"
    r = runner.invoke(app, ["calibrate", str(few), "--pattern", "10x7", "--square", "25", "--out", str(out)])
    assert r.exit_code == EXIT_FAILED and not out.exists()
    assert "show a 9x6 chessboard (inner corners), not 10x7: give --pattern 9x6" in r.output


@pytest.mark.parametrize(
    "module, name, warning, field, extra",
    [
        (
            "doorloc.vision.board_response",
            "board_response",
            "camera response was",
            "response_gamma",
            ["--no-optics"],
        ),
        ("doorloc.photometric.check", "measure_detected", "camera optics were", "photometric_model", []),
    ],
)
def test_a_failing_extra_measurement_does_not_cost_the_calibration(
    messy_dir, tmp_path, monkeypatch, module, name, warning, field, extra
):
    def broken(*a, **k):
        raise ValueError("synthetic failure")

    monkeypatch.setattr(importlib.import_module(module), name, broken)
    out = tmp_path / "camera.yaml"
    r = runner.invoke(
        app, ["calibrate", str(messy_dir), "--pattern", "9x6", "--square", "25", "--out", str(out), *extra]
    )
    assert r.exit_code == 0, r.output
    assert f"{warning} not measured (ValueError: synthetic failure)" in r.output
    assert "Traceback" not in r.output
    cal = load_calibration(out)
    assert getattr(cal, field) is None and abs(cal.camera.fx / 535.916 - 1) < 0.01


@pytest.mark.slow
def test_optics_measured_on_the_same_photographs_go_into_the_calibration_and_the_cell(messy_dir, tmp_path):
    """By default (``--optics``) a chessboard's calibration carries the board check's photometric model
    (OpenCV's left camera compresses its highlights from about 0.69 of full scale), with what made it, and a
    cell that names the file carries it (so locate reads the measured response and edge residual, not its
    doubts for an unmeasured camera)."""
    out = tmp_path / "camera.yaml"
    r = runner.invoke(
        app,
        ["calibrate", str(messy_dir), "--pattern", "9x6", "--square", "25", "--out", str(out)],
    )
    assert r.exit_code == 0, r.output
    cal = load_calibration(out)
    assert cal.photometric_model is not None and abs(cal.camera.fx / 535.916 - 1) < 0.01
    model = PhotometricModel.from_dict(cal.photometric_model)
    assert 0.6 < model.shoulder < 0.8 and 0.0 < model.residual_edge_px < 0.13
    assert "doorloc calibrate messy" in (cal.photometric_model_provenance or "")
    assert "13 photographs" in (cal.photometric_model_provenance or "")
    assert "camera optics: measured on 13 photographs" in r.output and "not measured" not in r.output
    assert f"compresses the levels above {model.shoulder:.2f} of full scale" in r.output
    (tmp_path / "cell.yaml").write_text(
        "camera:\n  calibration: camera.yaml\n"
        "  extrinsics: {rvec: [1.5707963268, 0, 0], tvec_mm: [-30, 40, 350]}\n"
    )
    assert load_cell(tmp_path / "cell.yaml").camera_photometry == model


def test_a_failing_response_measurement_does_not_cost_the_optics_measurement(
    messy_dir, tmp_path, monkeypatch
):
    import doorloc.photometric.check as check
    import doorloc.vision.board_response as response

    def broken(*a, **k):
        raise ValueError("synthetic failure")

    monkeypatch.setattr(response, "board_response", broken)
    monkeypatch.setattr(check, "measure_detected", broken)  # the optics tried (and failed fast) all the same
    out = tmp_path / "camera.yaml"
    r = runner.invoke(
        app, ["calibrate", str(messy_dir), "--pattern", "9x6", "--square", "25", "--out", str(out)]
    )
    assert r.exit_code == 0, r.output
    assert "camera response was not measured (ValueError: synthetic failure)" in r.output
    assert "camera optics were not measured (ValueError: synthetic failure)" in r.output


def test_a_12_bit_cameras_depth_is_read_off_its_photographs(tmp_path):
    """Photographs of a 12-bit camera that stores its levels from 0 in 16-bit files: the calibration file
    says ``stored_bits: 12`` (so that a cell naming it reads its doors at that depth) and the command says
    so; the same photographs in 8 bits write no depth."""
    if not OPENCV_LEFT.is_dir():
        pytest.fail("real data missing: clone the repository with shared/ beside it")
    d = tmp_path / "twelve"
    d.mkdir()
    for p in sorted(OPENCV_LEFT.glob("left*.jpg"))[:8]:
        grey = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        cv2.imwrite(str(d / (p.stem + ".png")), np.rint(grey * (4095 / 255)).astype(np.uint16))
    out = tmp_path / "camera.yaml"
    args = ["calibrate", str(d), "--pattern", "9x6", "--square", "25", "--out", str(out), "--no-optics"]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    assert load_calibration(out).stored_bits == 12
    assert "12 bits stored from 0 in 16-bit photographs" in r.output
