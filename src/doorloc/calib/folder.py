"""Detect a board in a folder (or list) of images and calibrate: the one flow the CLI, benches and tests share.

``doorloc calibrate``, ``bench/bench_calib_real.py``, ``bench/bench_calib_rendered.py`` and the calibration
tests all go read -> :func:`~doorloc.calib.detect.scan_images` -> :class:`~doorloc.calib.calibrate.View` ->
:func:`~doorloc.calib.calibrate.calibrate_views` through the functions here, so what a benchmark measures is
what the command does.

- :func:`read_image_file` / :func:`read_folder`: images as stored (EXIF orientation ignored), each unreadable
  file kept with a sentence saying why;
- :func:`detect_views`: board views of the images of the most common size (others skipped with a reason);
- :func:`calibrate_detected`: the calibration of those views (model chosen by held-out error);
- :func:`calibrate_folder` = :func:`read_folder` + :func:`detect_views` + :func:`calibrate_detected`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from doorloc.calib.calibrate import (
    CANDIDATES,
    MIN_VIEWS,
    CalibrationError,
    CalibrationResult,
    Candidate,
    View,
    calibrate_views,
)
from doorloc.calib.detect import BoardScan, CharucoSpec, Chessboard, SkippedImage, scan_images, stored_grey
from doorloc.calib.io import CalibrationFile

__all__ = [
    "IMAGE_SUFFIXES",
    "CalibrationInputError",
    "TooFewViewsError",
    "LoadedImage",
    "DetectedViews",
    "CalibrationOutcome",
    "read_image_file",
    "read_folder",
    "detect_views",
    "calibrate_detected",
    "calibrate_folder",
]

#: file name endings read as images (case-insensitive)
IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp"})

#: (name, image or None, why it could not be read or None), as :func:`scan_images` takes them
LoadedImage = tuple[str, np.ndarray | None, str | None]
Board = Chessboard | CharucoSpec


class CalibrationInputError(ValueError):
    """The images cannot be calibrated from at all (no folder, no image files); the message says which."""


class TooFewViewsError(CalibrationError):
    """Too few images show the board; ``detected`` says which were skipped and why."""

    def __init__(self, message: str, detected: DetectedViews) -> None:
        super().__init__(message)
        self.detected = detected


@dataclass(frozen=True)
class DetectedViews:
    """The board found in a set of images.

    Attributes
    ----------
    board : Chessboard or CharucoSpec
    scan : BoardScan
        Detections by image name, the skipped images with reasons, the shared image size (px).
    views : list of View
        One per detection, in image order; board points in mm, corners in px.
    n_images : int
        How many images were offered (read or not).
    background : ndarray or None
        The first image with a board (grey or BGR), for the report's picture; None if none or not 1/3 channels.
    """

    board: Board
    scan: BoardScan
    views: list[View]
    n_images: int
    background: np.ndarray | None = None

    @property
    def skipped(self) -> list[SkippedImage]:
        return self.scan.skipped


@dataclass(frozen=True)
class CalibrationOutcome:
    """A folder's calibration: what was detected and what the calibration found."""

    detected: DetectedViews
    result: CalibrationResult

    def calibration_file(self, camera_name: str = "doorloc") -> CalibrationFile:
        """The calibration as written to ``camera.yaml`` (RMS and per-view RMS in px, the chosen model)."""
        fit = self.result.fit
        return CalibrationFile(
            self.result.camera,
            fit.rms_px,
            fit.per_view_rms_px,
            camera_name,
            {"model": fit.candidate.name},
            self.result.covariance,
            tuple(self.result.covariance_names),
        )


def full_board_views(
    images: Sequence[LoadedImage], scan: BoardScan, board: Chessboard
) -> list[tuple[np.ndarray, np.ndarray]]:
    """(grey image at its stored depth, 8 or 16 bits, every inner corner in the board's row-major order) for
    each image in which ``scan`` found the whole chessboard: the input of
    :func:`doorloc.vision.board_response.board_response`, which reads a response on the levels as stored."""
    n = board.cols * board.rows
    dets = scan.detections
    return [
        (stored_grey(img), dets[name].corners_px[np.argsort(dets[name].ids)])
        for name, img, _ in images
        if img is not None and name in dets and dets[name].ids.size == n
    ]


def read_image_file(path: str | os.PathLike) -> tuple[np.ndarray | None, str | None]:
    """``(image, None)`` or ``(None, reason)`` for one file; pixels as stored (EXIF orientation ignored)."""
    try:
        data = np.fromfile(os.fspath(path), dtype=np.uint8)
    except OSError as e:
        return None, f"cannot be read: {e.strerror or e}"
    if data.size == 0:
        return None, "is empty"
    im = cv2.imdecode(data, cv2.IMREAD_UNCHANGED | cv2.IMREAD_IGNORE_ORIENTATION)
    if im is None:
        return None, "is not an image OpenCV can decode (corrupt or unsupported format)"
    return im, None


def read_folder(images_dir: str | os.PathLike, glob: str = "*") -> list[LoadedImage]:
    """Every image file in ``images_dir`` matching ``glob``, sorted by name.

    Raises
    ------
    CalibrationInputError
        ``images_dir`` is not a folder, or holds no image file (by :data:`IMAGE_SUFFIXES`).
    """
    folder = Path(images_dir)
    if not folder.is_dir():
        raise CalibrationInputError(f"{folder} is not a folder of images")
    files = sorted(p for p in folder.glob(glob) if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise CalibrationInputError(f"no image files ({', '.join(sorted(IMAGE_SUFFIXES))}) in {folder}")
    return [(p.name, *read_image_file(p)) for p in files]


def detect_views(images: Sequence[LoadedImage], board: Board, *, refine: bool = True) -> DetectedViews:
    """Find ``board`` in each image (see :func:`scan_images`) and turn each detection into a :class:`View`."""
    scan = scan_images(list(images), board, refine=refine)
    views = [View(name, d.object_points(board), d.corners_px, d.ids) for name, d in scan.detections.items()]
    background = None
    if scan.detections:
        first = next(iter(scan.detections))
        im = next(im for name, im, _ in images if name == first)
        background = im if im is not None and (im.ndim == 2 or im.shape[2] == 3) else None
    return DetectedViews(board, scan, views, len(images), background)


def calibrate_detected(
    detected: DetectedViews,
    *,
    candidates: Sequence[Candidate] = CANDIDATES,
    n_folds: int = 5,
    min_views: int = MIN_VIEWS,
    reject: bool = True,
) -> CalibrationOutcome:
    """Calibrate the detected views (:func:`calibrate_views`: outliers rejected, model by held-out error).

    Raises
    ------
    TooFewViewsError
        Fewer than ``min_views`` images show the board; nothing to write.
    CalibrationError
        No model could be fitted.
    """
    n_views, size = len(detected.views), detected.scan.image_size
    if size is None or n_views < min_views:
        raise TooFewViewsError(
            f"only {n_views} of {detected.n_images} images show the board; calibration needs "
            f"at least {min_views}",
            detected,
        )
    result = calibrate_views(
        detected.views,
        size,
        candidates=tuple(candidates),
        n_folds=n_folds,
        min_views=min_views,
        reject=reject,
    )
    return CalibrationOutcome(detected, result)


def calibrate_folder(
    images_dir: str | os.PathLike,
    board: Board,
    *,
    glob: str = "*",
    candidates: Sequence[Candidate] = CANDIDATES,
    n_folds: int = 5,
    min_views: int = MIN_VIEWS,
) -> CalibrationOutcome:
    """Calibrate a camera from the board photographs in ``images_dir`` (one camera, one image size).

    Parameters
    ----------
    images_dir : path
        Folder of photographs; files matching ``glob`` with an image suffix are read.
    board : Chessboard or CharucoSpec
        The board (square side in mm).
    candidates, n_folds, min_views
        As :func:`~doorloc.calib.calibrate.calibrate_views`.

    Raises
    ------
    CalibrationInputError
        No folder or no image files in it.
    TooFewViewsError
        Too few images show the board (the error carries the detections and the skipped images).
    CalibrationError
        No model fits.
    """
    detected = detect_views(read_folder(images_dir, glob), board)
    return calibrate_detected(detected, candidates=candidates, n_folds=n_folds, min_views=min_views)
