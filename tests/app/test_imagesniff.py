"""Image kind and declared size from the header bytes alone, for every format OpenCV writes for us."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.app.imagesniff import ImageHeader, sniff_image, sniff_kind

EXT = {"png": ".png", "jpeg": ".jpg", "tiff": ".tif", "bmp": ".bmp"}


def _encode(kind: str, w: int, h: int, channels: int = 1) -> bytes:
    img = np.random.default_rng(w * 1000 + h).integers(
        0, 255, (h, w, channels) if channels > 1 else (h, w), np.uint8
    )
    ok, buf = cv2.imencode(EXT[kind], img)
    assert ok
    return buf.tobytes()


@settings(max_examples=40, deadline=None)
@given(
    kind=st.sampled_from(sorted(EXT)),
    w=st.integers(1, 300),
    h=st.integers(1, 300),
    channels=st.sampled_from([1, 3]),
)
def test_declared_size_matches_the_encoded_image(kind, w, h, channels):
    assert sniff_image(_encode(kind, w, h, channels)) == ImageHeader(kind, w, h)


def test_16_bit_png_and_tiff():
    img = np.zeros((37, 53), np.uint16)
    for kind in ("png", "tiff"):
        assert sniff_image(cv2.imencode(EXT[kind], img)[1].tobytes()) == ImageHeader(kind, 53, 37)


def test_jpeg_size_after_a_large_exif_block():
    from io import BytesIO

    from PIL import Image

    exif = Image.Exif()
    exif[0x010E] = "x" * 30_000  # ImageDescription: pushes the frame header 30 kB in
    buf = BytesIO()
    Image.new("L", (321, 123)).save(buf, format="JPEG", exif=exif.tobytes())
    assert sniff_image(buf.getvalue()) == ImageHeader("jpeg", 321, 123)


@pytest.mark.parametrize("kind", sorted(EXT))
def test_truncated_header_gives_the_kind_without_a_size(kind):
    data = _encode(kind, 64, 48)
    assert sniff_image(data[:9]) == ImageHeader(kind)
    assert sniff_image(data[:9]).pixels is None


@pytest.mark.parametrize(
    "data", [b"", b"hello world", b"GIF89a......", b"%PDF-1.7\n", b"\x00" * 100, b"RIFF....WEBPVP8 "]
)
def test_other_bytes_are_not_images(data):
    assert sniff_image(data) is None
    assert sniff_kind(data[:8]) is None
