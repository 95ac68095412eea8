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
from dataclasses import dataclass, field

__all__ = [
    "ImageHeader",
    "sniff_image",
    "sniff_kind",
    "decode_limit_problem",
    "IMAGE_KINDS",
    "MAGIC_BYTES_NEEDED",
    "HEADER_BYTES_NEEDED",
]

IMAGE_KINDS = ("png", "jpeg", "tiff", "bmp")
#: bytes that :func:`sniff_kind` needs to tell the kind
MAGIC_BYTES_NEEDED = 8
#: bytes that hold the size of any image these readers know (JPEG's frame header may follow a large EXIF block)
HEADER_BYTES_NEEDED = 256 * 1024

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers carry the image size; C4 (DHT), C8 (JPG) and CC (DAC) share the range but are not frames.
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


@dataclass(frozen=True)
class ImageHeader:
    """What an image's header says: its kind and declared size in pixels (None when the header is cut short)."""

    kind: str
    width: int | None = None
    height: int | None = None
    #: samples per pixel once decoded (grey 1, grey+alpha 2, colour 3, colour+alpha 4); None: unknown (assume 4)
    channels: int | None = field(default=None, compare=False)
    #: bytes per sample once decoded (8-bit 1, 16-bit 2); None: unknown (assume 2)
    sample_bytes: int | None = field(default=None, compare=False)

    @property
    def pixels(self) -> int | None:
        """Declared ``width * height``, or None when unknown."""
        if self.width is None or self.height is None:
            return None
        return self.width * self.height

    @property
    def decoded_bytes(self) -> int | None:
        """Memory the decoded image takes: width x height x channels x bytes per sample (unknowns assumed large)."""
        if self.pixels is None:
            return None
        return self.pixels * (self.channels or 4) * (self.sample_bytes or 2)


def decode_limit_problem(
    header: ImageHeader, name: str, max_pixels: int, max_decoded_bytes: int
) -> str | None:
    """Why an image must not be decoded (a sentence), or None when its declared size is within both limits.

    Checked before decoding: a 381 kB PNG can declare 7000 x 7000 16-bit RGBA pixels (392 MB once decoded).
    """
    if header.pixels is None:
        return None
    if header.pixels > max_pixels:
        return (
            f"the image '{name}' declares {header.width}x{header.height} pixels ({header.pixels / 1e6:.1f} MP), "
            f"more than is decoded here ({max_pixels / 1e6:.1f} MP)"
        )
    decoded = header.decoded_bytes or 0
    if decoded > max_decoded_bytes:
        return (
            f"the image '{name}' ({header.width}x{header.height}, {header.channels or '?'} channel(s) of "
            f"{8 * (header.sample_bytes or 2)} bits) would take {decoded / 1e6:.0f} MB decoded, more than is "
            f"decoded here ({max_decoded_bytes / 1e6:.0f} MB)"
        )
    return None


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
    if len(size) == 4:
        return ImageHeader(kind, size[0], size[1], size[2], size[3])
    return ImageHeader(kind, size[0], size[1])


#: PNG colour type -> channels OpenCV decodes it to (palette images become BGR)
_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}


def _png_size(data: bytes) -> tuple[int, ...] | None:
    # The IHDR chunk must come first: 4-byte length, 'IHDR', width, height (big-endian), bit depth, colour type.
    if data[12:16] != b"IHDR":
        return None
    width, height, depth, colour = struct.unpack(">IIBB", data[16:26])
    return width, height, _PNG_CHANNELS.get(colour, 4), 2 if depth > 8 else 1


def _jpeg_size(data: bytes) -> tuple[int, ...] | None:
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
            precision, height, width, components = struct.unpack(">BHHB", data[i + 4 : i + 10])
            return width, height, components, 2 if precision > 8 else 1
        if marker in (0xD9, 0xDA):  # end of image / start of scan before any frame header
            return None
        i += 2 + length
    return None


def _tiff_size(data: bytes) -> tuple[int, ...] | None:
    endian = "<" if data[:2] == b"II" else ">"
    (ifd,) = struct.unpack(endian + "I", data[4:8])
    (count,) = struct.unpack(endian + "H", data[ifd : ifd + 2])
    width = height = None
    samples, bits = 1, 8
    for k in range(count):
        entry = data[ifd + 2 + 12 * k : ifd + 14 + 12 * k]
        tag, typ, n_values = struct.unpack(endian + "HHI", entry[:8])
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
        elif tag == 277:
            samples = value
        elif tag == 258:
            # with several samples the values sit elsewhere; 16 is the safe guess then (the limit errs large)
            bits = value if n_values == 1 else 16
    if width is None or height is None:
        return None
    return width, height, samples, 2 if bits > 8 else 1


def _bmp_size(data: bytes) -> tuple[int, ...] | None:
    (dib,) = struct.unpack("<I", data[14:18])
    if dib == 12:  # BITMAPCOREHEADER: 16-bit unsigned sizes
        width, height, _planes, bits = struct.unpack("<HHHH", data[18:26])
    else:  # BITMAPINFOHEADER and later: signed 32-bit, negative height = top-down rows
        width, height, _planes, bits = struct.unpack("<iiHH", data[18:30])
    return abs(width), abs(height), 4 if bits == 32 else 3, 1
