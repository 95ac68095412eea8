"""The photometric model as an optional section of a calibration file: written, read back by doorloc and by
OpenCV, tolerated by a reader that does not know it, refused when malformed."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from doorloc.calib.camera import CameraModel
from doorloc.calib.io import (
    CalibrationFile,
    CalibrationFileError,
    dump_opencv_yaml,
    dump_ros_yaml,
    parse_calibration,
)
from doorloc.photometric.model import PhotometricModel

CAM = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)
MODEL = PhotometricModel(gamma=0.77, shoulder=0.4, print_spread_mm=-0.03)


def _cal() -> CalibrationFile:
    return CalibrationFile(
        CAM, photometric_model=MODEL.to_dict(), photometric_model_provenance="doorloc check-model --boards x"
    )


@pytest.mark.parametrize("dump", [dump_opencv_yaml, dump_ros_yaml])
def test_round_trip(dump):
    back = parse_calibration(dump(_cal()))
    assert back.photometric_model is not None
    assert PhotometricModel.from_dict(back.photometric_model) == MODEL
    assert back.photometric_model_provenance == "doorloc check-model --boards x"
    assert "photometric_model" not in back.extra


def test_opencv_reads_the_section(tmp_path):
    p = tmp_path / "camera.yaml"
    p.write_text(dump_opencv_yaml(_cal()))
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
    assert fs.getNode("photometric_model").getNode("gamma").real() == pytest.approx(0.77)
    np.testing.assert_allclose(fs.getNode("camera_matrix").mat(), CAM.camera_matrix)
    fs.release()


def test_file_without_section_reads_as_before():
    back = parse_calibration(dump_opencv_yaml(CalibrationFile(CAM)))
    assert back.photometric_model is None and back.photometric_model_provenance is None


def test_malformed_section_is_refused_with_its_name():
    text = dump_opencv_yaml(CalibrationFile(CAM)) + "photometric_model:\n   gamma: fast\n"
    with pytest.raises(CalibrationFileError, match="photometric_model.gamma"):
        parse_calibration(text)
