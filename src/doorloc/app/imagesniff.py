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
    "decode_limit_code",
    "DEFAULT_MAX_JPEG_SCANS",
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
    #: bytes per sample once decoded (8-bit 1, 16-bit 2, 32-bit 4); None: unknown (assume 2)
    sample_bytes: int | None = field(default=None, compare=False)
    #: JPEG: scans in the file (a progressive decoder passes over the whole image once per scan); else None
    scans: int | None = field(default=None, compare=False, repr=False)
    #: JPEG: a progressive frame (its decoder holds every DCT coefficient, 2 bytes each, besides the pixels)
    progressive: bool = field(default=False, compare=False, repr=False)
    #: TIFF: bytes of one decoded tile or strip (the decoder's buffer, whatever the image's own size); else None
    tile_bytes: int | None = field(default=None, compare=False, repr=False)
    #: samples that are not unsigned integers (TIFF SampleFormat float or signed): never decoded here
    odd_samples: bool = field(default=False, compare=False, repr=False)

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

    @property
    def work_bytes(self) -> int | None:
        """Memory the decoder needs at its peak: the decoded image, plus a progressive JPEG's coefficients
        (2 bytes per sample) or a TIFF's tile buffer; None when the size is unknown."""
        decoded = self.decoded_bytes
        if decoded is None:
            return None
        extra = 0
        if self.progressive:
            extra = self.pixels * (self.channels or 3) * 2  # type: ignore[operator]
        if self.tile_bytes is not None:
            extra = max(extra, self.tile_bytes)
        return decoded + extra


#: scans a JPEG may hold: libjpeg writes 10 for a progressive file, 1 for a baseline one; each scan costs
#: a pass over the whole image, so 60,000 near-empty scans in 908 kB cost 12 s of decoding
DEFAULT_MAX_JPEG_SCANS = 100


def decode_limit_code(header: ImageHeader, max_pixels: int, max_decoded_bytes: int) -> str:
    """The problem code of an image :func:`decode_limit_problem` refused: ``too_many_pixels`` when its size is
    past the limits, ``decode_limit`` when the decoding work is (scans, tiles, sample type)."""
    pixels, decoded = header.pixels or 0, header.decoded_bytes or 0
    return "too_many_pixels" if pixels > max_pixels or decoded > max_decoded_bytes else "decode_limit"


def decode_limit_problem(
    header: ImageHeader,
    name: str,
    max_pixels: int,
    max_decoded_bytes: int,
    max_jpeg_scans: int = DEFAULT_MAX_JPEG_SCANS,
) -> str | None:
    """Why an image must not be decoded (a sentence), or None when the work its header declares is within the limits.

    Checked before decoding, from the header alone: a 381 kB PNG can declare 7000 x 7000 16-bit RGBA pixels
    (392 MB once decoded); a 908 kB progressive JPEG 60,000 scans (12 s of CPU); a 260 kB TIFF of 64x64 pixels
    16368x16368-pixel tiles (1 GB of tile buffer); ``max_decoded_bytes`` bounds the decoder's peak memory
    (:attr:`ImageHeader.work_bytes`), ``max_jpeg_scans`` its passes.
    """
    if header.odd_samples or (header.sample_bytes or 1) > 2:
        return (
            f"the image '{name}' holds {8 * (header.sample_bytes or 4)}-bit or non-integer samples; "
            "only 8- and 16-bit unsigned images are decoded here"
        )
    if header.scans is not None and header.scans > max_jpeg_scans:
        return (
            f"the JPEG '{name}' holds {header.scans} scans, more than are decoded here ({max_jpeg_scans}; "
            "a camera writes 1, or about 10 when progressive)"
        )
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
    work = header.work_bytes or 0
    if work > max_decoded_bytes:
        why = "its tiles" if header.tile_bytes is not None else "its progressive coefficients"
        return (
            f"the image '{name}' ({header.width}x{header.height}) would need {work / 1e6:.0f} MB to decode "
            f"with {why}, more than is decoded here ({max_decoded_bytes / 1e6:.0f} MB)"
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
    if isinstance(size, ImageHeader):
        return size
    if size is None:
        # a JPEG whose frame header cannot be read may still hold too many scans
        return ImageHeader(kind, scans=_jpeg_scans(data)) if kind == "jpeg" else ImageHeader(kind)
    return ImageHeader(kind, size[0], size[1], size[2], size[3])


#: PNG colour type -> channels OpenCV decodes it to (palette images become BGR)
_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}


def _png_size(data: bytes) -> tuple[int, int, int, int] | None:
    # The IHDR chunk must come first: 4-byte length, 'IHDR', width, height (big-endian), bit depth, colour type.
    if data[12:16] != b"IHDR":
        return None
    width, height, depth, colour = struct.unpack(">IIBB", data[16:26])
    return width, height, _PNG_CHANNELS.get(colour, 4), 2 if depth > 8 else 1


def _jpeg_scans(data: bytes) -> int:
    # Start-of-scan markers: 0xFF 0xDA cannot occur inside entropy-coded data (0xFF is stuffed there with 0x00),
    # so counting them over the whole file is exact up to an embedded thumbnail's own scans.
    return data.count(b"\xff\xda")


def _jpeg_size(data: bytes) -> ImageHeader | None:
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
            return ImageHeader(
                "jpeg",
                width,
                height,
                components,
                2 if precision > 8 else 1,
                scans=_jpeg_scans(data),
                progressive=marker in (0xC2, 0xC6, 0xCA, 0xCE),
            )
        if marker in (0xD9, 0xDA):  # end of image / start of scan before any frame header
            return None
        i += 2 + length
    return None


#: TIFF field types whose values this reader uses: SHORT (2 bytes) and LONG (4 bytes)
_TIFF_SIZES = {3: ("H", 2), 4: ("I", 4)}


def _tiff_values(data: bytes, endian: str, entry: bytes) -> list[int]:
    """The values of one IFD entry (SHORT or LONG), read in place or at their offset; [] for other types."""
    _tag, typ, count = struct.unpack(endian + "HHI", entry[:8])
    if typ not in _TIFF_SIZES or count == 0:
        return []
    code, size = _TIFF_SIZES[typ]
    count = min(count, 16)  # the values read here are per sample: 16 is more samples than any camera writes
    if count * size <= 4:
        raw = entry[8 : 8 + count * size]
    else:
        (offset,) = struct.unpack(endian + "I", entry[8:12])
        raw = data[offset : offset + count * size]
    return list(struct.unpack(endian + code * count, raw))


def _tiff_size(data: bytes) -> ImageHeader | None:
    endian = "<" if data[:2] == b"II" else ">"
    (ifd,) = struct.unpack(endian + "I", data[4:8])
    (count,) = struct.unpack(endian + "H", data[ifd : ifd + 2])
    tags: dict[int, list[int]] = {}
    for k in range(count):
        entry = data[ifd + 2 + 12 * k : ifd + 14 + 12 * k]
        (tag,) = struct.unpack(endian + "H", entry[:2])
        values = _tiff_values(data, endian, entry)
        if values:
            tags[tag] = values
    if 256 not in tags or 257 not in tags:
        return None
    width, height = tags[256][0], tags[257][0]
    samples = tags.get(277, [1])[0]
    bits = max(tags.get(258, [8]))
    sample_bytes = max(1, -(-bits // 8))
    odd = any(f != 1 for f in tags.get(339, [1]))  # SampleFormat: 1 unsigned; 2 signed, 3 float, 4 void
    # the decoder's buffer: one tile (TileWidth x TileLength) or one strip (width x RowsPerStrip)
    if 322 in tags or 323 in tags:
        tile_px = tags.get(322, [width])[0] * tags.get(323, [height])[0]
    else:
        tile_px = width * min(tags.get(278, [height])[0], height)
    return ImageHeader(
        "tiff",
        width,
        height,
        samples,
        sample_bytes,
        tile_bytes=tile_px * samples * sample_bytes,
        odd_samples=odd,
    )


def _bmp_size(data: bytes) -> tuple[int, int, int, int] | None:
    (dib,) = struct.unpack("<I", data[14:18])
    if dib == 12:  # BITMAPCOREHEADER: 16-bit unsigned sizes
        width, height, _planes, bits = struct.unpack("<HHHH", data[18:26])
    else:  # BITMAPINFOHEADER and later: signed 32-bit, negative height = top-down rows
        width, height, _planes, bits = struct.unpack("<iiHH", data[18:30])
    return abs(width), abs(height), 4 if bits == 32 else 3, 1
