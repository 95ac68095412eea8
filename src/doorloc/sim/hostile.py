"""Image files made to cost a decoder far more than their size: what the service's hostile-client tests and
benchmark send (a service must refuse them from their header, before decoding).

Written by hand: no imaging library writes a JPEG with empty scans or a TIFF whose tiles dwarf the image,
since no honest encoder makes them.
"""

from __future__ import annotations

import struct

import cv2
import numpy as np

__all__ = ["progressive_jpeg_bomb", "tiff_header"]


def progressive_jpeg_bomb(extra_scans: int, side: int = 1024) -> bytes:
    """A progressive ``side`` x ``side`` grey JPEG with ``extra_scans`` copies of its last scan header (no
    data) before its end: each costs the decoder a pass over the image, a dozen bytes on the wire."""
    img = np.random.default_rng(0).integers(0, 255, (side, side), np.uint8)
    data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])[1].tobytes()
    last = data.rfind(b"\xff\xda")
    (length,) = struct.unpack(">H", data[last + 2 : last + 4])
    eoi = data.rfind(b"\xff\xd9")
    return data[:eoi] + data[last : last + 2 + length] * extra_scans + data[eoi:]


def tiff_header(
    width: int,
    height: int,
    tile: int | None,
    bits: int = 8,
    sample_format: int = 1,
    data_bytes: int = 64,
) -> bytes:
    """A little-endian one-sample TIFF declaring ``width`` x ``height`` pixels of ``bits`` bits
    (``sample_format`` 1 unsigned, 3 float), in ``tile`` x ``tile`` tiles when given (else one strip),
    followed by ``data_bytes`` zero bytes of image data."""
    tags = [(256, 4, width), (257, 4, height), (258, 3, bits), (259, 3, 1), (262, 3, 1), (277, 3, 1)]
    tags.append((339, 3, sample_format))
    data_offset = 8 + 2 + 12 * (len(tags) + 4) + 4
    if tile is not None:
        tags += [(322, 4, tile), (323, 4, tile), (324, 4, data_offset), (325, 4, data_bytes)]
    else:
        tags += [(273, 4, data_offset), (278, 4, height), (279, 4, data_bytes)]
    tags.sort()
    ifd = struct.pack("<H", len(tags))
    for tag, typ, value in tags:
        ifd += struct.pack("<HHI", tag, typ, 1) + (
            struct.pack("<HH", value, 0) if typ == 3 else struct.pack("<I", value)
        )
    ifd += struct.pack("<I", 0)
    head = b"II*\x00" + struct.pack("<I", 8) + ifd
    return head + b"\x00" * (data_offset - len(head)) + bytes(data_bytes)
