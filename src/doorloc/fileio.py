"""Writing output files so that a failure never leaves a half-written one behind.

Every file doorloc writes (calibrations, cell files, reports, overlays, rendered data sets) goes to a
temporary file in the destination folder, is flushed to disk, and then replaces the destination by an
atomic rename: readers see the old file or the new one, never a torn one.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["atomic_write_bytes", "atomic_write_text", "atomic_write_image"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and an atomic rename.

    The file gets the permissions a plain ``open(path, "w")`` would give (0666 less the umask),
    not the 0600 of the temporary file.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """UTF-8 text version of :func:`atomic_write_bytes`."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_image(path: str | os.PathLike, image: np.ndarray) -> None:
    """Encode ``image`` by the file's suffix (.png, .jpg, .tif, ...) and write it atomically.

    Raises ValueError when OpenCV cannot encode that format.
    """
    import cv2

    p = Path(path)
    try:
        ok, buf = cv2.imencode(p.suffix or ".png", image)
    except cv2.error:  # no encoder for this suffix
        ok = False
    if not ok:
        raise ValueError(f"cannot encode an image as {p.suffix or '.png'}; use a .png or .jpg file name")
    atomic_write_bytes(p, buf.tobytes())
