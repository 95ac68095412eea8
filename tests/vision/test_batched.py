"""The batched (torch) locate path gives the one-frame answers: every step search bit for bit, every frame's
corner within 0.01 px and pose within 0.001 mm, the same refusals; frames it cannot take fall back, and say so."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="the batched path needs the optional torch extra")

from doorloc.vision import batched  # noqa: E402
from doorloc.vision.coarse import coarse_edges  # noqa: E402
from doorloc.vision.locate import locate, locate_steps  # noqa: E402

_spec = importlib.util.spec_from_file_location("locate_golden", Path(__file__).with_name("locate_golden.py"))
assert _spec is not None and _spec.loader is not None
golden = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("locate_golden", golden)
_spec.loader.exec_module(golden)


_CUDA = pytest.mark.skipif(not torch.cuda.is_available(), reason="torch sees no CUDA device here")


def _close(a, b) -> list[str]:
    """Batched vs one-frame: the same refusal, corner within 0.01 px, pose within 0.001 mm."""
    if (a.ok, a.error_code) != (b.ok, b.error_code):
        return [f"{a.ok}/{a.error_code} != {b.ok}/{b.error_code}"]
    if not a.ok:
        return [] if a.error == b.error else [f"message {a.error!r} != {b.error!r}"]
    bad = [k for k in ("x_mm", "z_mm", "thickness_mm") if abs(getattr(a, k) - getattr(b, k)) > 1e-3]
    bad += ["yaw_deg"] * bool(abs(a.yaw_deg - b.yaw_deg) > 1e-4)
    bad += ["corner_px"] * bool(np.max(np.abs(np.subtract(a.corner_px, b.corner_px))) > 0.01)
    return bad


# one test process makes the module's fixtures (the golden cases and their one-frame answers) for all its tests
pytestmark = pytest.mark.xdist_group("batched")


@pytest.fixture(scope="module")
def cases():
    return list(golden.all_cases())


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=_CUDA)])
def test_every_step_search_equals_the_one_frame_finder(cases, device):
    # Collect the step searches the one-frame path makes on the fixtures, then answer them all at once.
    frames, queries, want = [], [], []
    for _, cell, door, img in cases:
        if img.dtype != np.uint8 or img.ndim != 2 or img.shape != (1080, 1920):
            continue
        b = len(frames)
        frames.append(img)
        g = locate_steps(img, cell, door)
        try:
            q = next(g)
            while True:
                ans = coarse_edges(q.plane, **q.kwargs)
                # (a search on the frame's levels mapped through a camera model, the shoulder's doubt on
                # arris doors, is answered on its own plane, not by the frames' finder)
                if q.plane is img:
                    queries.append((b, q.kwargs))
                    want.append(ans)
                q = g.send(ans)
        except StopIteration:
            pass
    assert len(queries) > 300
    finder = batched.TorchStepFinder(torch.from_numpy(np.stack(frames)).to(device))
    got = finder.answer(queries)
    for (b, kw), (ga, gs), (wa, ws) in zip(queries, got, want, strict=True):
        assert ga.dtype == wa.dtype and gs.dtype == ws.dtype
        assert np.array_equal(ga, wa, equal_nan=True), (b, kw["axis"])
        assert np.array_equal(gs, ws), (b, kw["axis"])


@pytest.fixture(scope="module")
def one_frame(cases):
    return {name: locate(img, cell, door, image_name=name) for name, cell, door, img in cases}


DEVICE_FINDERS = [("cpu", "auto"), ("cpu", "torch"), pytest.param("cuda", "auto", marks=_CUDA)]


@pytest.mark.parametrize(("device", "finder"), DEVICE_FINDERS)
def test_batched_answers_equal_the_one_frame_answers(cases, one_frame, device, finder):
    by_cell: dict[int, list] = {}
    for name, cell, door, img in cases:
        by_cell.setdefault(id(cell), []).append((name, cell, door, img))
    bad, fallbacks = {}, {}
    for group in by_cell.values():
        cell = group[0][1]
        for start in range(0, len(group), 16):
            part = group[start : start + 16]
            answers = batched.locate_batch(
                [c[3] for c in part],
                cell,
                [c[2] for c in part],
                names=[c[0] for c in part],
                device=device,
                finder=finder,
            )
            for (name, *_), a in zip(part, answers, strict=True):
                assert a.result.image == name
                diff = _close(a.result, one_frame[name])
                if diff:
                    bad[name] = diff
                if a.fallback:
                    fallbacks[name] = a.fallback
    assert not bad, bad
    # 8-bit frames of the camera's size are batched (colour ones too); the others fall back and say why
    assert set(fallbacks) == {
        "derived/float_pixels",
        "derived/wrong_size",
        "derived/two_channels",
        "derived/uint16",
    }
    assert "16" in fallbacks["derived/uint16"] and "1280x720" in fallbacks["derived/wrong_size"]


@pytest.mark.parametrize("finder", ["torch", "plane"])
def test_a_failing_batched_search_falls_back_to_the_one_frame_path(cases, monkeypatch, finder):
    name, cell, door, img = next(c for c in cases if c[0] == "grid/img_0040.png")

    def broken(self, queries):
        raise RuntimeError("device lost")

    cls = batched.TorchStepFinder if finder == "torch" else batched.PlaneStepFinder
    monkeypatch.setattr(cls, "answer", broken)
    (a,) = batched.locate_batch([img], cell, door, names=[name], finder=finder)
    assert a.fallback and "device lost" in a.fallback
    assert not _close(a.result, locate(img, cell, door, image_name=name))


def test_unknown_or_missing_device_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown device"):
        batched.resolve_device("tpu")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="no CUDA"):
            batched.resolve_device("cuda")
    assert batched.resolve_device("auto").type in ("cpu", "cuda")
    with pytest.raises(ValueError, match="unknown step finder"):
        batched.locate_batch([], None, finder="gpu")  # type: ignore[arg-type]


def test_each_frames_jpeg_quality_reaches_its_locate(cases):
    """Batched and fallen-back frames are located with their own file's JPEG quality, as one-frame."""
    name, cell, door, img = next(c for c in cases if c[0] == "grid/img_0040.png")
    deep = img.astype(np.uint16) * 257  # not 8-bit: through the one-frame path
    got = batched.locate_batch([img, img, deep], cell, door, jpeg_qualities=[0, 85, 70], finder="plane")
    assert [a.result.diagnostics.get("jpeg_quality") for a in got] == [None, 85, 70]
    assert got[2].fallback and not got[1].fallback
    assert not _close(got[1].result, locate(img, cell, door, jpeg_quality=85))
    with pytest.raises(ValueError, match="one per frame"):
        batched.locate_batch([img], cell, door, jpeg_qualities=[80, 80])


@pytest.mark.parametrize("finder", ["torch", "plane"])
def test_a_search_on_mapped_levels_is_answered_on_them(cases, one_frame, finder):
    # The arris fixtures reach above the shoulder's knee with the response unchecked: each is located a
    # second time on its levels mapped through a shouldered camera (doorloc.vision.response_shoulder), whose
    # step searches the frames' finder does not hold; batched, that reading is the one-frame path's.
    shouldered = [c for c in cases if "move_x_mm" in one_frame[c[0]].diagnostics.get("response_shoulder", {})]
    assert len(shouldered) >= 4
    part = shouldered[:4]
    answers = batched.locate_batch(
        [c[3] for c in part], part[0][1], [c[2] for c in part], names=[c[0] for c in part], finder=finder
    )
    for (name, *_), a in zip(part, answers, strict=True):
        want = one_frame[name]
        assert not a.fallback and a.result.uncertainty == want.uncertainty
        assert a.result.diagnostics["response_shoulder"] == want.diagnostics["response_shoulder"]
