"""Image files and bytes in, arrays out: the only place in doorloc.vision that touches files.

Images are decoded with OpenCV's ``IMREAD_UNCHANGED | IMREAD_IGNORE_ORIENTATION``: 8- or 16-bit,
grey, BGR or BGRA, exactly as stored (no EXIF rotation, which would silently break the calibration).
A JPEG's quality (:func:`stored_jpeg_quality`) is read from its quantization table, which the decoded array
no longer shows: locate's JPEG doubt follows it.
"""

from __future__ import annotations

import functools
import io
import os
from pathlib import Path

import numpy as np

__all__ = [
    "JPEG_LUMINANCE_TABLE",
    "ImageDecodeError",
    "decode_image",
    "jpeg_quality",
    "libjpeg_luminance_table",
    "read_image",
    "read_stored_image",
    "stored_jpeg_quality",
]

#: the JPEG standard's luminance quantization table (ITU-T T.81 Annex K.1), row by row: libjpeg's quality
#: 50, which its other qualities scale
JPEG_LUMINANCE_TABLE = np.array(
    [
        [16, 11, 10, 16, 24, 40, 51, 61],
        [12, 12, 14, 19, 26, 58, 60, 55],
        [14, 13, 16, 24, 40, 57, 69, 56],
        [14, 17, 22, 29, 51, 87, 80, 62],
        [18, 22, 37, 56, 68, 109, 103, 77],
        [24, 35, 55, 64, 81, 104, 113, 92],
        [49, 64, 78, 87, 103, 121, 120, 101],
        [72, 92, 95, 98, 112, 100, 103, 99],
    ],
    float,
).ravel()


class ImageDecodeError(ValueError):
    """The bytes or the file are not an image OpenCV can decode; the message says which and why."""


def _flags() -> int:
    import cv2

    return cv2.IMREAD_UNCHANGED | cv2.IMREAD_IGNORE_ORIENTATION


def decode_image(data: bytes, name: str = "image") -> np.ndarray:
    """Decode an encoded image (PNG, JPEG, TIFF, BMP, ...) held in memory.

    Parameters
    ----------
    data : bytes
        The encoded file contents.
    name : str
        What to call the image in an error message.

    Returns
    -------
    ndarray
        ``(H, W)`` grey or ``(H, W, C)`` BGR(A), dtype uint8 or uint16, as stored.

    Raises
    ------
    ImageDecodeError
        Empty data, or bytes that are not a supported image format.
    """
    import cv2

    if not data:
        raise ImageDecodeError(f"{name}: no image data (0 bytes); send the camera image file itself")
    buf = np.frombuffer(data, dtype=np.uint8)
    try:
        img = cv2.imdecode(buf, _flags())
    except cv2.error as e:  # a corrupt header can make a decoder throw instead of returning None
        raise ImageDecodeError(
            f"{name}: cannot decode the image ({e.msg if hasattr(e, 'msg') else e})"
        ) from None
    if img is None or img.size == 0:
        raise ImageDecodeError(
            f"{name}: not a readable image ({len(data)} bytes); expected PNG, JPEG, TIFF or BMP from the camera"
        )
    if img.dtype not in (np.uint8, np.uint16):
        raise ImageDecodeError(f"{name}: unsupported pixel type {img.dtype}; use 8- or 16-bit images")
    return img


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file; see :func:`decode_image` for what comes back.

    Raises
    ------
    ImageDecodeError
        The file cannot be read or is not an image.
    """
    return decode_image(_file_bytes(path), name=str(Path(path)))


def read_stored_image(path: str | os.PathLike) -> tuple[np.ndarray, int]:
    """Read an image file as :func:`read_image` does, with the JPEG quality it was stored at
    (:func:`stored_jpeg_quality`, 0 where it is no JPEG): what ``locate(..., jpeg_quality=)`` is told.

    Raises
    ------
    ImageDecodeError
        The file cannot be read or is not an image.
    """
    data = _file_bytes(path)
    return decode_image(data, name=str(Path(path))), stored_jpeg_quality(data)


def _file_bytes(path: str | os.PathLike) -> bytes:
    p = Path(path)
    try:
        return p.read_bytes()
    except OSError as e:
        raise ImageDecodeError(f"cannot read image {p}: {e.strerror or e}") from None


def libjpeg_luminance_table(quality: int) -> np.ndarray:
    """libjpeg's luminance table at ``quality`` (1-100), row by row (its ``jpeg_quality_scaling``)."""
    scale = 5000.0 / quality if quality < 50 else 200.0 - 2.0 * quality
    return np.clip(np.floor((JPEG_LUMINANCE_TABLE * scale + 50.0) / 100.0), 1.0, 255.0)


def jpeg_quality(luminance_table: np.ndarray) -> int:
    """The libjpeg quality (1-100) whose luminance table is nearest to ``luminance_table`` (64 values, row by
    row) in log ratio: exact for libjpeg's and OpenCV's files, the nearest strength for a camera's own
    tables."""
    t = np.log(np.clip(np.asarray(luminance_table, float).ravel(), 1.0, None))
    if t.size != 64:
        raise ValueError(f"a JPEG quantization table has 64 values, got {t.size}")
    cost = np.sum((_libjpeg_log_tables() - t) ** 2, axis=1)
    return int(np.argmin(cost)) + 1


@functools.cache
def _libjpeg_log_tables() -> np.ndarray:
    """``(100, 64)``: the log of libjpeg's luminance table at each quality 1-100 (made once: every JPEG
    upload reads its quality against them)."""
    tables = np.log([libjpeg_luminance_table(q) for q in range(1, 101)])
    tables.flags.writeable = False
    return tables


def stored_jpeg_quality(data: bytes) -> int:
    """The JPEG quality an encoded image was stored at (:func:`jpeg_quality` of its luminance table), 0 for
    bytes that are not a JPEG or whose tables cannot be read (the decoder then decides what they are)."""
    if not data.startswith(b"\xff\xd8"):
        return 0
    # Pillow reads a JPEG's quantization tables from its header; OpenCV decodes a JPEG without giving them
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(io.BytesIO(data)) as im:
            tables = getattr(im, "quantization", None)
    except (OSError, UnidentifiedImageError, ValueError):
        return 0
    if not tables or 0 not in tables or len(tables[0]) != 64:
        return 0
    return jpeg_quality(np.asarray(tables[0], float))
