"""Every way an image file reaches locate tells it the file's JPEG quality (0 for a lossless file): the
quality sets locate's JPEG doubt, which an image without noise cannot show by its blocks."""

from __future__ import annotations

import cv2
import numpy as np
from fastapi.testclient import TestClient

from doorloc.app.answer import DoorChoice
from doorloc.app.batch import locate_item, plan_batch
from doorloc.app.decodepool import DecodePool
from doorloc.app.http import create_app
from doorloc.app.services import answer_image

from .conftest import dev_settings, stand_in_locate


def _door_image() -> np.ndarray:
    img = np.full((48, 64), 128, np.uint8)
    img[20:, 30:] = 200
    return img


def _jpeg(quality: int) -> bytes:
    return cv2.imencode(".jpg", _door_image(), [cv2.IMWRITE_JPEG_QUALITY, quality])[1].tobytes()


def _png() -> bytes:
    return cv2.imencode(".png", _door_image())[1].tobytes()


def _capturing(seen: list[int]):
    def capture(image, cell, door, **kw):
        seen.append(kw["jpeg_quality"])
        return stand_in_locate(image, cell, door, **kw)

    return capture


def quality_locate(image, cell, door, *, image_name="", trace=None, jpeg_quality=0):
    """A locate in a worker process that says which quality it was told."""
    from doorloc.vision.result import LocateResult

    return LocateResult.refusal(image_name, "no_door", f"told quality {jpeg_quality}")


def test_the_service_reads_the_quality_from_the_bytes_and_keeps_a_given_one(cell):
    seen: list[int] = []
    choice = DoorChoice(door=cell.default_door)
    for data in (_jpeg(85), _png(), _jpeg(60)):
        answer_image(data, cell, choice, image_name="d", locate_fn=_capturing(seen))
    answer_image(_door_image(), cell, choice, image_name="d", locate_fn=_capturing(seen))
    answer_image(_door_image(), cell, choice, image_name="d", locate_fn=_capturing(seen), jpeg_quality=92)
    assert seen == [85, 0, 60, 0, 92]


def test_the_http_route_tells_locate_the_uploads_quality(cell, store):
    seen: list[int] = []
    app = create_app(dev_settings(), cell=cell, store=store, locate_fn=_capturing(seen))
    with TestClient(app) as c:
        for name, data, kind in (("d.jpg", _jpeg(90), "image/jpeg"), ("d.png", _png(), "image/png")):
            r = c.post("/v1/locate", files={"image": (name, data, kind)})
            assert r.status_code == 200, r.text
    assert seen == [90, 0]


def test_a_locating_worker_is_told_the_quality(cell):
    with DecodePool(1, cpu_s=5, memory_bytes=300_000_000, locate_fn=quality_locate, locate_cpu_s=5) as pool:
        pool.start()
        for data, quality in ((_jpeg(77), 77), (_png(), 0)):
            r = pool.decode_and_locate(
                data,
                "d",
                cell,
                cell.default_door,
                max_decoded_bytes=10**8,
                timeout_s=60,
                jpeg_quality=quality,
            ).result
            assert r.error == f"told quality {quality}"


def test_a_batch_tells_locate_each_files_quality(cell, tmp_path):
    (tmp_path / "a.jpg").write_bytes(_jpeg(70))
    (tmp_path / "b.png").write_bytes(_png())
    seen: list[int] = []
    for item in plan_batch(tmp_path, cell):
        assert locate_item(item, cell, locate_fn=_capturing(seen))["status"] in ("answered", "refused")
    assert sorted(seen) == [0, 70]
