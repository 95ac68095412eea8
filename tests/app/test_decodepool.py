"""Decoding in limited worker processes, and the decoders' work read from the header before decoding."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from doorloc.app.decodepool import DecodePool, DecodeRefused, start_pools
from doorloc.app.imagesniff import decode_limit_problem, sniff_image
from doorloc.sim.hostile import progressive_jpeg_bomb


def test_header_gives_the_scan_count_and_the_coefficient_buffer():
    plain = sniff_image(cv2.imencode(".jpg", np.zeros((30, 40), np.uint8))[1].tobytes())
    assert plain.scans == 1 and not plain.progressive and plain.work_bytes == 30 * 40
    bomb = sniff_image(progressive_jpeg_bomb(500, side=64))
    assert bomb.progressive and bomb.scans > 500
    assert bomb.work_bytes == 64 * 64 * (1 + 2)  # pixels, plus 2-byte coefficients
    assert "scans" in decode_limit_problem(bomb, "b.jpg", 50_000_000, 100_000_000, max_jpeg_scans=100)
    assert decode_limit_problem(bomb, "b.jpg", 50_000_000, 100_000_000, max_jpeg_scans=1000) is None


def test_tiff_float_samples_are_four_bytes_and_refused():
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.zeros((30, 40), np.float32)).save(buf, format="TIFF")
    h = sniff_image(buf.getvalue())
    assert h.sample_bytes == 4 and h.odd_samples
    assert "32-bit" in decode_limit_problem(h, "f.tif", 50_000_000, 100_000_000)


@pytest.fixture(scope="module")
def pool():
    with DecodePool(1, cpu_s=1, memory_bytes=300_000_000) as p:
        yield p


def test_a_normal_image_decodes_as_in_process(pool):
    img = np.random.default_rng(2).integers(0, 65535, (90, 120, 3), np.uint16)
    out = pool.decode(cv2.imencode(".png", img)[1].tobytes(), "door.png", timeout_s=60)
    assert out.dtype == np.uint16 and np.array_equal(out, img)
    # the worker's CPU time for a decode is told (a request's Server-Timing counts it): 16 MP of noise
    big = np.random.default_rng(3).integers(0, 65535, (4000, 4000), np.uint16)
    out, cpu_s = pool.decode_costed(cv2.imencode(".png", big)[1].tobytes(), "big.png", timeout_s=60)
    assert np.array_equal(out, big) and cpu_s > 0.01, cpu_s


def test_a_decoder_past_its_cpu_limit_is_ended_and_replaced(pool):
    with pytest.raises(DecodeRefused) as e:
        pool.decode(progressive_jpeg_bomb(40_000), "bomb.jpg", timeout_s=120)  # ~7 s of decoding
    assert e.value.status == 422 and e.value.code == "decode_limit" and "CPU" in e.value.detail
    assert pool.decode(cv2.imencode(".png", np.ones((4, 4), np.uint8))[1].tobytes(), "a.png", 60).shape == (
        4,
        4,
    )
    assert pool.killed >= 1


def test_a_decode_past_its_memory_limit_is_refused(pool):
    big = cv2.imencode(".png", np.zeros((12000, 14000), np.uint16))[1].tobytes()  # 336 MB decoded
    with pytest.raises(DecodeRefused) as e:
        pool.decode(big, "big.png", timeout_s=120)
    assert e.value.status == 422 and e.value.code == "decode_limit" and "MB of memory" in e.value.detail


def test_the_deadline_answers_503(pool):
    with pytest.raises(DecodeRefused) as e:
        pool.decode(progressive_jpeg_bomb(40_000), "bomb.jpg", timeout_s=0.2)
    assert e.value.status == 503 and e.value.code == "overloaded"
    assert pool.decode(cv2.imencode(".png", np.ones((4, 4), np.uint8))[1].tobytes(), "a.png", 60).shape == (
        4,
        4,
    )


def test_undecodable_bytes_are_422(pool):
    with pytest.raises(DecodeRefused) as e:
        pool.decode(b"\x89PNG\r\n\x1a\n" + b"\0" * 100, "cut.png", timeout_s=60)
    assert e.value.status == 422 and e.value.code == "undecodable_image"


# ---------------------------------------------------------------------------------------------- locating


def spinning_locate(image, cell, door, *, image_name="", trace=None, jpeg_quality=0):
    """A locate that an image makes pathological: it never ends (a worker must be ended from outside)."""
    if int(image[0, 0]) == 255:
        while True:
            pass
    from doorloc.vision.result import LocateResult

    return LocateResult.refusal(image_name, "no_door", f"{image.shape} seen")


def _thesis_cell():
    from doorloc.cell import load_cell

    from .conftest import CELL_PATH

    return load_cell(CELL_PATH)


def test_pools_started_together_hold_every_worker_ready_and_each_answers():
    """start_pools starts the workers of several pools at once; each pool then holds its size in ready
    workers (none started twice by a second call), and a job in either is answered."""
    quiet = cv2.imencode(".png", np.zeros((6, 8), np.uint8))[1].tobytes()
    with (
        DecodePool(2, cpu_s=5, memory_bytes=300_000_000) as first,
        DecodePool(1, cpu_s=5, memory_bytes=300_000_000) as second,
    ):
        start_pools([first, second])
        start_pools([first, second])
        assert (len(first._workers), len(second._workers)) == (2, 1)
        assert all(w.process.is_alive() for w in first._workers + second._workers)
        assert first.decode(quiet, "q.png", timeout_s=60).shape == (6, 8)
        assert second.decode(quiet, "q.png", timeout_s=60).shape == (6, 8)
        assert (len(first._workers), len(second._workers)) == (2, 1)


def test_a_locate_past_its_cpu_limit_ends_its_worker_and_the_next_is_answered():
    cell = _thesis_cell()
    quiet = cv2.imencode(".png", np.zeros((6, 8), np.uint8))[1].tobytes()
    wild = cv2.imencode(".png", np.full((6, 8), 255, np.uint8))[1].tobytes()
    with DecodePool(1, cpu_s=1, memory_bytes=300_000_000, locate_fn=spinning_locate, locate_cpu_s=1) as pool:
        pool.start()

        def located(png: bytes, name: str):
            return pool.decode_and_locate(
                png, name, cell, cell.default_door, max_decoded_bytes=10**8, timeout_s=60
            ).result

        assert "(6, 8) seen" in located(quiet, "q.png").error
        with pytest.raises(DecodeRefused) as e:
            located(wild, "w.png")
        assert (e.value.status, e.value.code) == (422, "locate_limit") and "CPU time" in e.value.detail
        assert pool.killed == 1
        # a fresh worker answers the next image (decoding alone too: one pool for both)
        assert located(quiet, "q.png").ok is False
        assert pool.decode(quiet, "q.png", timeout_s=60).shape == (6, 8)


def test_one_job_refuses_a_decoding_bomb_as_a_decode_and_the_next_image_is_located():
    """Decoding and locating run as one job in one worker: a decoding bomb ends that worker with the decode
    wording (422 decode_limit, never locate_limit), a fresh worker takes its place and locates the next image;
    an image that decodes larger than accepted is refused before locate runs."""
    cell = _thesis_cell()
    quiet = cv2.imencode(".png", np.zeros((6, 8), np.uint8))[1].tobytes()
    with DecodePool(1, cpu_s=1, memory_bytes=300_000_000, locate_fn=spinning_locate, locate_cpu_s=1) as pool:
        pool.start()
        first = pool._workers[0].process.pid
        with pytest.raises(DecodeRefused) as e:
            pool.decode_and_locate(
                progressive_jpeg_bomb(40_000),  # ~7 s of decoding
                "bomb.jpg",
                cell,
                cell.default_door,
                max_decoded_bytes=10**8,
                timeout_s=120,
            )
        assert (e.value.status, e.value.code) == (422, "decode_limit"), e.value.detail
        assert e.value.detail.startswith("Decoding the image took more than 1 s of CPU time"), e.value.detail
        assert pool.killed == 1
        got = pool.decode_and_locate(
            quiet, "q.png", cell, cell.default_door, max_decoded_bytes=10**8, timeout_s=60
        )
        assert "(6, 8) seen" in got.result.error and got.overlay_png is None
        assert [w.process.pid for w in pool._workers] != [first]  # the bomb's worker was replaced
        # decoded to more than accepted: 422 too_many_pixels, and locate never ran (the image would spin it)
        wild = cv2.imencode(".png", np.full((60, 80), 255, np.uint8))[1].tobytes()
        with pytest.raises(DecodeRefused) as e:
            pool.decode_and_locate(
                wild, "w.png", cell, cell.default_door, max_decoded_bytes=4000, timeout_s=60
            )
        assert (e.value.status, e.value.code) == (
            422,
            "too_many_pixels",
        ) and "'w.png' decoded to" in e.value.detail
        assert pool.killed == 1


def test_one_job_says_which_step_the_deadline_stopped():
    cell = _thesis_cell()
    wild = cv2.imencode(".png", np.full((6, 8), 255, np.uint8))[1].tobytes()
    with DecodePool(1, cpu_s=5, memory_bytes=300_000_000, locate_fn=spinning_locate, locate_cpu_s=30) as pool:
        pool.start()
        with pytest.raises(DecodeRefused) as e:
            pool.decode_and_locate(
                progressive_jpeg_bomb(40_000),
                "b.jpg",
                cell,
                cell.default_door,
                max_decoded_bytes=10**8,
                timeout_s=0.3,
            )
        assert (e.value.status, e.value.code) == (503, "overloaded") and "not decoded" in e.value.detail
        # (its worker was ended: the next image waits for the fresh one, which loads locate's kernels)
        quiet = cv2.imencode(".png", np.zeros((6, 8), np.uint8))[1].tobytes()
        assert not pool.decode_and_locate(
            quiet, "q.png", cell, cell.default_door, max_decoded_bytes=10**8, timeout_s=120
        ).result.ok
        with pytest.raises(DecodeRefused) as e:
            pool.decode_and_locate(
                wild, "w.png", cell, cell.default_door, max_decoded_bytes=10**8, timeout_s=3
            )
        assert (e.value.status, e.value.code) == (503, "overloaded") and "not located" in e.value.detail
