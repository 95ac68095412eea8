"""Image files and bytes in, arrays out: the only place in doorloc.vision that touches files.

Images are decoded with OpenCV's ``IMREAD_UNCHANGED | IMREAD_IGNORE_ORIENTATION``: 8- or 16-bit,
grey, BGR or BGRA, exactly as stored (no EXIF rotation, which would silently break the calibration).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["ImageDecodeError", "decode_image", "read_image"]


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
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ImageDecodeError(f"cannot read image {p}: {e.strerror or e}") from None
    return decode_image(data, name=str(p))
