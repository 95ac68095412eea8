"""Camera models, calibration files, checkerboard/ChArUco calibration and cell calibration."""

from doorloc.calib.camera import CameraModel, DistortionValidity, Extrinsics, PosedCamera, distortion_validity
from doorloc.calib.io import CalibrationFile, CalibrationFileError, load_calibration, save_calibration

__all__ = [
    "CameraModel",
    "Extrinsics",
    "PosedCamera",
    "DistortionValidity",
    "distortion_validity",
    "CalibrationFile",
    "CalibrationFileError",
    "load_calibration",
    "save_calibration",
]
