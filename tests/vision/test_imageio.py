"""The JPEG quality read from an encoded image's own quantization table."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from doorloc.vision.imageio import decode_image, stored_jpeg_quality


def _encoded(suffix: str, **params: int) -> bytes:
    img = (np.random.default_rng(3).random((48, 40, 3)) * 255).astype(np.uint8)
    flags = [cv2.IMWRITE_JPEG_QUALITY, params["quality"]] if "quality" in params else []
    if params.get("progressive"):
        flags += [cv2.IMWRITE_JPEG_PROGRESSIVE, 1]
    ok, buf = cv2.imencode(suffix, img, flags)
    assert ok
    return buf.tobytes()


@pytest.mark.parametrize("quality", [25, 70, 80, 88, 95, 100])
@pytest.mark.parametrize("progressive", [False, True])
def test_a_jpegs_quality_is_read_from_its_bytes(quality, progressive):
    data = _encoded(".jpg", quality=quality, progressive=progressive)
    assert stored_jpeg_quality(data) == quality
    assert decode_image(data).shape == (48, 40, 3)


@pytest.mark.parametrize("suffix", [".png", ".tif", ".bmp"])
def test_a_lossless_file_has_no_jpeg_quality(suffix):
    assert stored_jpeg_quality(_encoded(suffix)) == 0


@pytest.mark.parametrize("data", [b"", b"\xff\xd8", b"\xff\xd8\xff\xdb\x00\x43garbage", b"not an image"])
def test_bytes_whose_tables_cannot_be_read_have_no_quality(data):
    assert stored_jpeg_quality(data) == 0
