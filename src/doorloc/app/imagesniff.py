"""Recognise an image by its first bytes and read the size its header declares, without decoding it.

The service and the batch runner decide what a file is from its content, never from its name or a
declared content type, and refuse an image whose header declares more pixels than they are willing to
decode before a single pixel is allocated. Only the four lossless-or-common formats a camera writes are
recognised: PNG, JPEG, TIFF and BMP.

Examples
--------
>>> import struct, zlib
>>> ihdr = struct.pack(">IIBBBBB", 50000, 50000, 8, 0, 0, 0, 0)
>>> png = b"\\x89PNG\\r\\n\\x1a\\n" + struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
>>> sniff_image(png)
ImageHeader(kind='png', width=50000, height=50000)
>>> sniff_image(b"hello") is None
True
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

__all__ = ["ImageHeader", "sniff_image", "sniff_kind", "IMAGE_KINDS", "MAGIC_BYTES_NEEDED"]

IMAGE_KINDS = ("png", "jpeg", "tiff", "bmp")
#: bytes that :func:`sniff_kind` needs to tell the kind
MAGIC_BYTES_NEEDED = 8

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers carry the image size; C4 (DHT), C8 (JPG) and CC (DAC) share the range but are not frames.
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


@dataclass(frozen=True)
class ImageHeader:
    """What an image's header says: its kind and declared size in pixels (None when the header is cut short)."""

    kind: str
    width: int | None = None
    height: int | None = None

    @property
    def pixels(self) -> int | None:
        """Declared ``width * height``, or None when unknown."""
        if self.width is None or self.height is None:
            return None
        return self.width * self.height


def sniff_kind(head: bytes) -> str | None:
    """The image kind ('png', 'jpeg', 'tiff', 'bmp') from the first bytes, or None for anything else."""
    if head.startswith(_PNG_SIGNATURE):
        return "png"
    if head.startswith(b"\xff\xd8\xff"):
        return "jpeg"
    if head.startswith((b"II*\x00", b"MM\x00*")):
        return "tiff"
    if head.startswith(b"BM") and len(head) >= 6:
        return "bmp"
    return None


def sniff_image(data: bytes) -> ImageHeader | None:
    """Kind and declared size of an encoded image, or None if the bytes are not a PNG/JPEG/TIFF/BMP.

    Parameters
    ----------
    data : bytes
        The encoded file (or at least its first few kilobytes; JPEG keeps its size after the EXIF block).

    Returns
    -------
    ImageHeader or None
        ``width``/``height`` are None when the header is truncated or malformed.
    """
    kind = sniff_kind(data[:MAGIC_BYTES_NEEDED])
    if kind is None:
        return None
    reader = {"png": _png_size, "jpeg": _jpeg_size, "tiff": _tiff_size, "bmp": _bmp_size}[kind]
    try:
        size = reader(data)
    except (struct.error, IndexError, ValueError):
        size = None
    if size is None:
        return ImageHeader(kind)
    return ImageHeader(kind, size[0], size[1])


def _png_size(data: bytes) -> tuple[int, int] | None:
    # The IHDR chunk must come first: 4-byte length, 'IHDR', width, height (big-endian).
    if data[12:16] != b"IHDR":
        return None
    return struct.unpack(">II", data[16:24])


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    i = 2
    n = len(data)
    while i + 4 <= n:
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:  # markers without a length
            i += 2
            continue
        (length,) = struct.unpack(">H", data[i + 2 : i + 4])
        if marker in _JPEG_SOF:
            height, width = struct.unpack(">HH", data[i + 5 : i + 9])
            return width, height
        if marker in (0xD9, 0xDA):  # end of image / start of scan before any frame header
            return None
        i += 2 + length
    return None


def _tiff_size(data: bytes) -> tuple[int, int] | None:
    endian = "<" if data[:2] == b"II" else ">"
    (ifd,) = struct.unpack(endian + "I", data[4:8])
    (count,) = struct.unpack(endian + "H", data[ifd : ifd + 2])
    width = height = None
    for k in range(count):
        entry = data[ifd + 2 + 12 * k : ifd + 14 + 12 * k]
        tag, typ, _n = struct.unpack(endian + "HHI", entry[:8])
        if typ == 3:  # SHORT
            (value,) = struct.unpack(endian + "H", entry[8:10])
        elif typ == 4:  # LONG
            (value,) = struct.unpack(endian + "I", entry[8:12])
        else:
            continue
        if tag == 256:
            width = value
        elif tag == 257:
            height = value
    if width is None or height is None:
        return None
    return width, height


def _bmp_size(data: bytes) -> tuple[int, int] | None:
    (dib,) = struct.unpack("<I", data[14:18])
    if dib == 12:  # BITMAPCOREHEADER: 16-bit unsigned sizes
        width, height = struct.unpack("<HH", data[18:22])
    else:  # BITMAPINFOHEADER and later: signed 32-bit, negative height = top-down rows
        width, height = struct.unpack("<ii", data[18:26])
    return abs(width), abs(height)
