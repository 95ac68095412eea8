"""Calibration and cell files: both calibration formats, real files, errors with the file named."""

from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.calib.io import (
    CalibrationFile,
    CalibrationFileError,
    dump_opencv_yaml,
    dump_ros_yaml,
    load_calibration,
    parse_calibration,
    save_calibration,
)
from doorloc.cell import CellFileError, DoorSize, Fixture, load_cell, parse_cell, save_cell
from doorloc.vision.config import LocateConfig


def test_reads_opencv_published_file(shared_data):
    cal = load_calibration(shared_data / "opencv-left" / "published_left_intrinsics.yml")
    assert cal.camera.fx == pytest.approx(535.916, abs=1e-3)
    assert cal.camera.image_size == (640, 480)
    assert cal.avg_reprojection_error == pytest.approx(0.393, abs=1e-3)
    assert max(cal.per_view_reprojection_errors) == pytest.approx(1.18, abs=0.01)


@pytest.mark.parametrize("fmt", ["opencv", "ros"])
def test_round_trip(tmp_path, fmt):
    cam = CameraModel.from_values(
        [[700.5, 0, 320.25], [0, 701.0, 240.0], [0, 0, 1]],
        [-0.2, 0.1, 1e-3, -2e-3, 0.01, 0.1, 0.02, 0.003],
        (640, 480),
        350.0,
    )
    cal = CalibrationFile(cam, 0.25, [0.2, 0.3], "cam0", response_gamma=2.15, response_gamma_sigma=0.12)
    path = tmp_path / f"c_{fmt}.yaml"
    save_calibration(cal, path, fmt)
    back = load_calibration(path)
    assert back.camera == cam and back.camera.observed_radius_px == 350.0
    assert back.avg_reprojection_error == 0.25 and back.per_view_reprojection_errors == [0.2, 0.3]
    # the response measured on the photographs travels with the file, as a value, not an unknown key
    assert (back.response_gamma, back.response_gamma_sigma) == (2.15, 0.12)
    assert not {"response_gamma", "response_gamma_sigma"} & set(back.extra)
    save_calibration(CalibrationFile(cam), path, fmt)
    assert load_calibration(path).response_gamma is None and "response_gamma" not in path.read_text()
    if fmt == "ros":
        assert "distortion_model: rational_polynomial" in path.read_text()


def test_opencv_can_read_what_we_write(tmp_path):
    cam = CameraModel.from_values(
        [[700.5, 0, 320.25], [0, 701.0, 240.0], [0, 0, 1]], [-0.2, 0.1, 0, 0, 0], (640, 480)
    )
    path = tmp_path / "c.yaml"
    path.write_text(dump_opencv_yaml(CalibrationFile(cam)))
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    np.testing.assert_array_equal(fs.getNode("camera_matrix").mat(), cam.camera_matrix)
    assert int(fs.getNode("image_width").real()) == 640
    path.write_text(dump_opencv_yaml(CalibrationFile(cam, response_gamma=2.2, response_gamma_sigma=0.05)))
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fs.getNode("response_gamma").real() == 2.2 and fs.getNode("response_gamma_sigma").real() == 0.05


def test_ros_output_has_spec_keys():
    cam = CameraModel.from_values(
        [[700.5, 0, 320.25], [0, 701.0, 240.0], [0, 0, 1]], [-0.2, 0.1, 0, 0, 0], (640, 480)
    )
    text = dump_ros_yaml(CalibrationFile(cam))
    for key in (
        "image_width",
        "image_height",
        "camera_name",
        "camera_matrix",
        "distortion_model",
        "distortion_coefficients",
        "rectification_matrix",
        "projection_matrix",
    ):
        assert f"{key}:" in text


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("camera_matrix: [1, 2", "not a YAML"),
        ("- 1\n- 2", "mapping"),
        ("image_width: 3", "missing key 'camera_matrix'"),
        (
            "camera_matrix: [[1,0,0],[0,1,0],[0,0,1]]\ndistortion_coefficients: [0,0,0]\nimage_width: 3\nimage_height: 3",
            "distortion coefficients",
        ),
    ],
)
def test_bad_calibration_text_names_the_problem(text, match):
    with pytest.raises(CalibrationFileError, match=match):
        parse_calibration(text, "x.yaml")


def test_missing_calibration_file_names_the_path(tmp_path):
    with pytest.raises(CalibrationFileError, match="nope.yaml"):
        load_calibration(tmp_path / "nope.yaml")


def test_failed_save_leaves_no_file(tmp_path):
    cam = CameraModel.from_values([[700.5, 0, 320.25], [0, 701.0, 240.0], [0, 0, 1]], [], (640, 480))
    with pytest.raises(ValueError):
        save_calibration(CalibrationFile(cam), tmp_path / "c.yaml", "xml")
    assert list(tmp_path.iterdir()) == []


def test_thesis_cell(thesis_cell_path):
    cell = load_cell(thesis_cell_path)
    assert cell.camera.image_size == (1920, 1080)
    assert cell.camera.fx == 1678.35
    assert cell.face_y(DoorSize(width_mm=900)) == 0.0
    # The nominal reference corner is in view.
    u, v = cell.posed_camera.project_cell(np.zeros((1, 3)))[0]
    assert 0 < u < 1920 and 0 < v < 1080


def test_face_y_follows_width():
    assert Fixture(900, 0, -0.5).face_y(1100) == -100
    assert Fixture(900, 5, 0).face_y(700) == 5
    assert Fixture(900, 0, -1).face_y(800) == 100


def test_cell_with_calibration_file_and_round_trip(tmp_path, thesis_cell_path):
    cell = load_cell(thesis_cell_path)
    save_calibration(CalibrationFile(cell.camera.with_observed_radius(900.0)), tmp_path / "camera.yaml")
    (tmp_path / "cell.yaml").write_text(
        "camera:\n  calibration: camera.yaml\n  extrinsics: {rvec: [1.5707963268, 0, 0], tvec_mm: [-30, 40, 350]}\n"
    )
    loaded = load_cell(tmp_path / "cell.yaml")
    assert loaded.camera == cell.camera and loaded.camera.observed_radius_px == 900.0
    save_cell(loaded, tmp_path / "cell2.yaml")
    again = load_cell(tmp_path / "cell2.yaml")
    assert again.camera == loaded.camera
    np.testing.assert_array_equal(again.extrinsics.tvec_mm, [-30, 40, 350])


def test_a_cell_takes_the_response_its_calibration_measured_unless_it_states_its_own(
    tmp_path, thesis_cell_path
):
    """doorloc calibrate writes the camera response it measured on the photographs into the calibration file:
    a cell that says nothing of the response takes it, known within its 2-sigma range; a cell that states
    an exponent, or the doubt, keeps its own."""
    cam = load_cell(thesis_cell_path).camera
    save_calibration(
        CalibrationFile(cam, response_gamma=2.2, response_gamma_sigma=0.11), tmp_path / "camera.yaml"
    )
    ext = "  extrinsics: {rvec: [1.5707963268, 0, 0], tvec_mm: [-30, 40, 350]}\n"
    (tmp_path / "cell.yaml").write_text("camera:\n  calibration: camera.yaml\n" + ext)
    cell = load_cell(tmp_path / "cell.yaml")
    assert cell.response_gamma == 2.2 and cell.locate.response_unmeasured_factor == pytest.approx(1.1)
    assert cell.response_gamma_sigma == 0.11
    # saved and read again (the model check's extended cell, camera inline): the same response and doubt
    save_cell(cell, tmp_path / "inline.yaml")
    back = load_cell(tmp_path / "inline.yaml")
    assert (back.response_gamma, back.response_gamma_sigma) == (2.2, 0.11)
    assert back.locate.response_unmeasured_factor == pytest.approx(1.1)
    (tmp_path / "own.yaml").write_text("camera:\n  calibration: camera.yaml\n  response_gamma: 1.0\n" + ext)
    own = load_cell(tmp_path / "own.yaml")
    assert (
        own.response_gamma == 1.0
        and own.response_gamma_sigma is None
        and own.locate.response_unmeasured_factor == LocateConfig().response_unmeasured_factor
    )
    (tmp_path / "own_sigma.yaml").write_text(
        "camera:\n  calibration: camera.yaml\n  response_gamma: 1.6\n  response_gamma_sigma: 0.08\n" + ext
    )
    own_sigma = load_cell(tmp_path / "own_sigma.yaml")
    assert own_sigma.response_gamma_sigma == 0.08
    assert own_sigma.locate.response_unmeasured_factor == pytest.approx(1.1)
    (tmp_path / "doubt.yaml").write_text(
        "camera:\n  calibration: camera.yaml\n" + ext + "locate: {response_unmeasured_factor: 1.5}\n"
    )
    doubt = load_cell(tmp_path / "doubt.yaml")
    assert doubt.response_gamma == 2.2 and doubt.locate.response_unmeasured_factor == 1.5


def test_a_cameras_stored_depth_travels_from_its_calibration_to_the_cell(tmp_path, thesis_cell_path):
    """``stored_bits`` (a 12-bit camera storing 0-4095 in 16-bit images, which doorloc calibrate reads off
    the board photographs) is kept by both calibration formats, taken by a cell that states none, overridden
    by one that states its own (``camera.stored_bits``), written by a saved cell; a depth outside 8-16 bits is
    an error naming the key."""
    cam = load_cell(thesis_cell_path).camera
    for fmt in ("opencv", "ros"):
        save_calibration(CalibrationFile(cam, stored_bits=12), tmp_path / f"c_{fmt}.yaml", fmt)
        back = load_calibration(tmp_path / f"c_{fmt}.yaml")
        assert back.stored_bits == 12 and "stored_bits" not in back.extra
    assert load_calibration(tmp_path / "c_opencv.yaml").stored_bits == 12
    save_calibration(CalibrationFile(cam), tmp_path / "plain.yaml")
    assert load_calibration(tmp_path / "plain.yaml").stored_bits is None
    assert "stored_bits" not in (tmp_path / "plain.yaml").read_text()
    ext = "  extrinsics: {rvec: [1.5707963268, 0, 0], tvec_mm: [-30, 40, 350]}\n"
    (tmp_path / "cell.yaml").write_text("camera:\n  calibration: c_opencv.yaml\n" + ext)
    cell = load_cell(tmp_path / "cell.yaml")
    assert cell.stored_bits == 12
    save_cell(cell, tmp_path / "inline.yaml")
    assert load_cell(tmp_path / "inline.yaml").stored_bits == 12
    (tmp_path / "own.yaml").write_text("camera:\n  calibration: c_opencv.yaml\n  stored_bits: 10\n" + ext)
    assert load_cell(tmp_path / "own.yaml").stored_bits == 10
    assert load_cell(thesis_cell_path).stored_bits is None
    (tmp_path / "bad.yaml").write_text("camera:\n  calibration: c_opencv.yaml\n  stored_bits: 20\n" + ext)
    with pytest.raises(CellFileError, match="stored_bits"):
        load_cell(tmp_path / "bad.yaml")
    (tmp_path / "bad_cal.yaml").write_text(
        (tmp_path / "c_opencv.yaml").read_text().replace("stored_bits: 12", "stored_bits: 7.5")
    )
    with pytest.raises(CalibrationFileError, match="stored_bits must be a whole number of bits"):
        load_calibration(tmp_path / "bad_cal.yaml")


@pytest.mark.parametrize(
    ("doc", "match"),
    [
        ({}, "missing key 'camera'"),
        ({"camera": {"image_size": [10, 10]}}, "camera_matrix"),
        ({"camera": {"calibration": "missing.yaml", "extrinsics": {}}}, "missing.yaml"),
        (
            {"camera": {"image_size": [10, 10], "camera_matrix": [[1, 0, 5], [0, 1, 5], [0, 0, 1]]}},
            "extrinsics",
        ),
        (
            {
                "camera": {
                    "image_size": [10, 10],
                    "camera_matrix": [[1, 0, 5], [0, 1, 5], [0, 0, 1]],
                    "extrinsics": {"rvec": [0, 0, 0], "tvec_mm": [0, 0, 1]},
                },
                "door": {"width_mm": -3},
            },
            "width_mm",
        ),
        (
            {
                "camera": {
                    "image_size": [10, 10],
                    "camera_matrix": [[1, 0, 5], [0, 1, 5], [0, 0, 1]],
                    "extrinsics": {"rvec": [0, 0, 0], "tvec_mm": [0, 0, 1]},
                },
                "locate": {"response_check": "sometimes"},
            },
            "response_check.*every_image.*where_unmeasured",
        ),
    ],
)
def test_bad_cell_names_the_problem(tmp_path, doc, match):
    with pytest.raises(CellFileError, match=match):
        parse_cell(doc, tmp_path, "cell.yaml")


@pytest.mark.parametrize(
    ("section", "key", "allowed"),
    [
        ("envelope", "x", "x_mm, z_mm, yaw_deg"),
        ("camera", "response_gama", "response_gamma"),
        ("door", "arris", "arris_profile"),
        ("locate", "min_contrst", "min_contrast"),
        (None, "bogus", "locate"),
    ],
)
def test_unknown_cell_key_is_named_with_the_allowed_ones(thesis_cell_path, section, key, allowed):
    doc = yaml.safe_load(Path(thesis_cell_path).read_text())
    (doc.setdefault(section, {}) if section else doc)[key] = 2
    with pytest.raises(CellFileError, match=f"unknown key '{(section + '.') if section else ''}{key}'") as e:
        parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml")
    assert allowed in str(e.value)


@pytest.mark.parametrize("policy", ["refuse", "report"])
def test_thickness_check_policy_is_read_from_the_cell(tmp_path, thesis_cell_path, policy):
    doc = yaml.safe_load(Path(thesis_cell_path).read_text())
    assert parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml").locate.thickness_check == "refuse"
    doc["locate"] = {"thickness_check": policy}
    assert parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml").locate.thickness_check == policy


def test_unknown_thickness_check_policy_is_an_error(thesis_cell_path):
    doc = yaml.safe_load(Path(thesis_cell_path).read_text())
    doc["locate"] = {"thickness_check": "ignore"}
    with pytest.raises(CellFileError, match="thickness_check") as e:
        parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml")
    assert "refuse" in str(e.value) and "report" in str(e.value)


def test_the_cells_light_is_read_as_a_direction_and_checked(thesis_cell_path):
    doc = yaml.safe_load(Path(thesis_cell_path).read_text())
    assert parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml").locate.light_direction_deg is None
    doc["locate"] = {"light_direction_deg": [70, 22.5]}
    cell = parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml")
    assert cell.locate.light_direction_deg == (70.0, 22.5)
    for bad in ([70], [70, 120], "west"):
        doc["locate"] = {"light_direction_deg": bad}
        with pytest.raises(CellFileError, match="light_direction_deg"):
            parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml")
    assert cell.locate.light_direction_sigma_deg == 10.0
    doc["locate"] = {"light_direction_deg": [70, 22.5], "light_direction_sigma_deg": 3}
    assert parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml").locate.light_direction_sigma_deg == 3.0
    for bad in (-1, 120, "a few"):
        doc["locate"] = {"light_direction_sigma_deg": bad}
        with pytest.raises(CellFileError, match="light_direction_sigma_deg"):
            parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml")


def test_the_doubt_of_unmeasured_optics_is_a_cell_setting_and_checked(thesis_cell_path):
    doc = yaml.safe_load(Path(thesis_cell_path).read_text())
    assert parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml").locate.optics_edge_sigma_px == 0.13
    doc["locate"] = {"optics_edge_sigma_px": 0}  # a rendered camera, known exactly
    assert parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml").locate.optics_edge_sigma_px == 0.0
    for bad in (-0.1, 7, "small"):
        doc["locate"] = {"optics_edge_sigma_px": bad}
        with pytest.raises(CellFileError, match="optics_edge_sigma_px"):
            parse_cell(doc, Path(thesis_cell_path).parent, "cell.yaml")


def test_cell_physical_settings_round_trip_and_hashes(tmp_path, thesis_cell_path):
    doc = yaml.safe_load(Path(thesis_cell_path).read_text())
    doc["camera"]["response_gamma"] = 2.2
    doc["door"]["arris_mm"], doc["door"]["arris_profile"] = 1.5, "round"
    doc["locate"] = {"door_brighter": False, "thickness_tolerance_mm": 0.5, "light_direction_deg": [70, 22.5]}
    doc["provenance"] = {"made_by": "test"}
    (tmp_path / "cell.yaml").write_text(yaml.safe_dump(doc))
    cell = load_cell(tmp_path / "cell.yaml")
    assert cell.response_gamma == 2.2 and cell.default_door.arris_profile == "round"
    assert cell.locate.door_brighter is False and cell.locate.thickness_tolerance_mm == 0.5
    assert cell.sha256 == hashlib.sha256((tmp_path / "cell.yaml").read_bytes()).hexdigest()
    save_cell(cell, tmp_path / "again.yaml")
    again = load_cell(tmp_path / "again.yaml")
    assert (again.response_gamma, again.default_door, again.locate, again.provenance) == (
        cell.response_gamma,
        cell.default_door,
        cell.locate,
        cell.provenance,
    )
    assert again.calibration_sha256 == cell.calibration_sha256  # the same camera model hashes the same
    bad = dict(doc, camera=dict(doc["camera"], response_gamma=0))
    with pytest.raises(CellFileError, match="camera.response_gamma"):
        parse_cell(bad, tmp_path, "cell.yaml")


# --- the OpenCV-format writer and reader checked against cv2.FileStorage itself --------------------------

# what YAML quoting gets wrong: quotes, backslashes, comment and mapping marks, line breaks, tabs, non-ASCII
_names = st.text(
    st.characters(codec="utf-8", exclude_categories=("Cs", "Cc", "Cn"))
    | st.sampled_from("\"\\#:\n\t\r'[]{}&*!|>%@`"),
    max_size=20,
)
_ncoeffs = st.sampled_from([0, 4, 5, 8, 12])


@st.composite
def calibration_files(draw) -> CalibrationFile:
    """Any calibration ``save_calibration`` accepts: every distortion length, optional quality figures."""
    fx, fy = draw(st.floats(50.0, 5000.0)), draw(st.floats(50.0, 5000.0))
    w, h = draw(st.integers(16, 8192)), draw(st.integers(16, 8192))
    cx, cy = draw(st.floats(0.0, float(w))), draw(st.floats(0.0, float(h)))
    n = draw(_ncoeffs)
    d = draw(st.lists(st.floats(-1.0, 1.0), min_size=n, max_size=n))
    radius = draw(st.none() | st.floats(1.0, 1e4))
    cam = CameraModel.from_values([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], d, (w, h), radius)
    avg = draw(st.none() | st.floats(0.0, 100.0))
    per_view = draw(st.lists(st.floats(0.0, 100.0), max_size=30))
    return CalibrationFile(cam, avg, per_view, draw(_names))


def _cv_read(path: Path) -> dict:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        assert fs.isOpened(), f"cv2.FileStorage could not open {path}"
        keys = fs.root().keys()
        out = {k: fs.getNode(k) for k in keys}
        return {
            "keys": set(keys),
            "camera_matrix": out["camera_matrix"].mat(),
            "distortion_coefficients": out["distortion_coefficients"].mat()
            if "distortion_coefficients" in out
            else None,
            "image_width": int(out["image_width"].real()),
            "image_height": int(out["image_height"].real()),
            "camera_name": out["camera_name"].string() if "camera_name" in out else None,
            "avg_reprojection_error": out["avg_reprojection_error"].real()
            if "avg_reprojection_error" in out
            else None,
            "per_view_reprojection_errors": out["per_view_reprojection_errors"].mat()
            if "per_view_reprojection_errors" in out
            else None,
            "observed_radius_px": out["observed_radius_px"].real() if "observed_radius_px" in out else None,
        }
    finally:
        fs.release()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cal=calibration_files())
def test_everything_we_write_opencv_reads_with_the_same_numbers(tmp_path, cal):
    path = tmp_path / "camera.yaml"
    save_calibration(cal, path, "opencv")
    cv = _cv_read(path)
    cam = cal.camera
    np.testing.assert_array_equal(cv["camera_matrix"], cam.camera_matrix)
    if len(cam.dist_coeffs):
        np.testing.assert_array_equal(cv["distortion_coefficients"].ravel(), cam.dist_coeffs)
    else:
        assert cv["distortion_coefficients"] is None or cv["distortion_coefficients"].size == 0
    assert (cv["image_width"], cv["image_height"]) == cam.image_size
    assert cv["camera_name"] == cal.camera_name
    assert cv["avg_reprojection_error"] == cal.avg_reprojection_error
    if cal.per_view_reprojection_errors:
        assert cv["per_view_reprojection_errors"].ravel().tolist() == cal.per_view_reprojection_errors
    else:
        assert cv["per_view_reprojection_errors"] is None
    assert cv["observed_radius_px"] == cam.observed_radius_px
    # and our own reader agrees with both
    back = load_calibration(path)
    assert back.camera == cam and back.camera.observed_radius_px == cam.observed_radius_px
    assert (back.avg_reprojection_error, back.per_view_reprojection_errors, back.camera_name) == (
        cal.avg_reprojection_error,
        cal.per_view_reprojection_errors,
        cal.camera_name,
    )


def _opencv_round_trips_name(path: Path, name: str) -> bool:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
    fs.write("camera_name", name)
    fs.release()
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError):  # OpenCV 5's binding sometimes reports its parse error as SystemError
        return False
    back = fs.getNode("camera_name").string()
    fs.release()
    return back == name


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cal=calibration_files(), dist_shape=st.sampled_from(["row", "column"]))
def test_we_read_what_opencv_writes(tmp_path, cal, dist_shape):
    path = tmp_path / "camera.yml"
    # OpenCV itself cannot read back some names it writes (a lone quote, ``true``, a trailing space):
    # the contract is that whatever OpenCV reads back, we read back the same.
    assume(_opencv_round_trips_name(tmp_path / "name.yml", cal.camera_name))
    cam = cal.camera
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
    fs.write("image_width", cam.image_size[0])
    fs.write("image_height", cam.image_size[1])
    fs.write("camera_name", cal.camera_name)
    fs.write("camera_matrix", cam.camera_matrix)
    if len(cam.dist_coeffs):
        d = cam.dist_coeffs.reshape(1, -1) if dist_shape == "row" else cam.dist_coeffs.reshape(-1, 1)
        fs.write("distortion_coefficients", d)
    if cal.avg_reprojection_error is not None:
        fs.write("avg_reprojection_error", cal.avg_reprojection_error)
    if cal.per_view_reprojection_errors:
        fs.write("per_view_reprojection_errors", np.asarray(cal.per_view_reprojection_errors).reshape(-1, 1))
    if cam.observed_radius_px is not None:
        fs.write("observed_radius_px", cam.observed_radius_px)
    fs.release()
    back = load_calibration(path)
    assert back.camera == cam and back.camera.observed_radius_px == cam.observed_radius_px
    assert back.avg_reprojection_error == cal.avg_reprojection_error
    assert back.per_view_reprojection_errors == cal.per_view_reprojection_errors
    assert back.camera_name == cal.camera_name


@pytest.mark.parametrize(
    "name", ["\u2028", "line\u2028sep", "para\u2029", "nel\x85", "del\x7f", "c1\x9b", "\ufffe"]
)
def test_a_name_opencv_reads_back_we_read_back(tmp_path, name):
    """Characters OpenCV writes raw inside its quotes and reads back, which YAML folds into a space (the line
    and paragraph separators, NEL) or cannot carry raw (DEL, C1 controls, U+FFFE): found by hypothesis in
    :func:`test_we_read_what_opencv_writes` (a name of one U+2028 was read as a space)."""
    path = tmp_path / "camera.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_name", name)
    fs.write("camera_matrix", np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]))
    fs.release()
    assert _opencv_round_trips_name(tmp_path / "name.yml", name)
    assert load_calibration(path).camera_name == name


@pytest.mark.parametrize("name", ["bell\x07", "nul\x00", "del\x7f", "\ufffe", "line\u2028separator"])
def test_camera_name_a_file_cannot_carry_is_refused_before_writing(tmp_path, name):
    cam = CameraModel.from_values([[700.5, 0, 320.25], [0, 701.0, 240.0], [0, 0, 1]], [], (640, 480))
    with pytest.raises(ValueError, match="camera_name"):
        save_calibration(CalibrationFile(cam, camera_name=name), tmp_path / "c.yaml")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "name", ["yes", "No", "Null", "~", "2001-12-14", "1.5", "12", "a: b", "#x", "[x]", "tab\there"]
)
def test_opencv_written_names_read_back_as_opencv_reads_them(tmp_path, name):
    """OpenCV's YAML has no booleans, nulls or dates: ``yes`` is the string ``yes`` to it, and to us."""
    path = tmp_path / "camera.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_name", name)
    fs.write("camera_matrix", np.array([[700.5, 0, 320.25], [0, 701.0, 240.0], [0, 0, 1]]))
    fs.release()
    assert _cv_read(path)["camera_name"] == name
    assert load_calibration(path).camera_name == name


@pytest.mark.parametrize("name", ["\\'", "a\\\\'b", "'\\", "it's \\n not a newline"])
def test_a_camera_name_with_backslashes_before_quotes_reads_back_as_written(tmp_path, name):
    """OpenCV writes a backslash as \\\\ and a quote as \\' ; a backslash before a quote (\\\\\\' ) must keep
    its backslash when the quote's escape is turned into YAML (the property test above drew the name \\')."""
    cam = CameraModel.from_values([[50, 0, 8], [0, 50, 8], [0, 0, 1]], [], (16, 16))
    path = tmp_path / "camera.yaml"
    save_calibration(CalibrationFile(cam, None, [], name), path, "opencv")
    assert _cv_read(path)["camera_name"] == name
    assert load_calibration(path).camera_name == name
