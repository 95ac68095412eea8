"""The speed work changes no answer: locate on every fixture (and inputs derived from them) gives the
poses recorded from the code before it, within 1e-4 mm, and the same refusals.

The recorded answers are ``data/locate_golden.json``; see ``locate_golden.py`` for how they were made
and when to record them again.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

from doorloc.vision.locate import locate

_spec = importlib.util.spec_from_file_location("locate_golden", Path(__file__).with_name("locate_golden.py"))
assert _spec is not None and _spec.loader is not None
golden = importlib.util.module_from_spec(_spec)
sys.modules["locate_golden"] = golden
_spec.loader.exec_module(golden)

WANT = json.loads(golden.GOLDEN.read_text())


def test_every_fixture_and_derived_case_is_recorded():
    names = [name for name, *_ in golden.all_cases()]
    assert sorted(names) == sorted(WANT)
    # the golden holds answers and refusals of many kinds, so parity covers both
    codes = {v["error_code"] for v in WANT.values()}
    assert None in codes and {"outside_envelope", "thickness_mismatch", "no_door", "edge_missing"} <= codes


def test_answers_and_refusals_are_as_recorded():
    bad = {}
    for name, cell, door, img in golden.all_cases():
        got = golden.summary(locate(img, cell, door, image_name=name))
        diff = golden.differences(got, WANT[name])
        if diff:
            bad[name] = diff
    assert not bad, f"{len(bad)} of {len(WANT)} cases differ from the recorded answers: {bad}"


def test_a_moved_pose_is_caught():
    # the comparison itself must be able to fail
    want = next(v for v in WANT.values() if v["ok"])
    moved = dict(want, x_mm=want["x_mm"] + 2e-4)
    assert golden.differences(moved, want)
    assert golden.differences(dict(want, ok=False, error_code="uncertain"), want)
    assert not golden.differences(dict(want), want)


@pytest.mark.parametrize("key", ["z_mm", "thickness_mm", "corner_px"])
def test_each_compared_field_is_checked(key):
    want = next(v for v in WANT.values() if v["ok"])
    v = want[key]
    moved = dict(want, **{key: [c + 1e-3 for c in v] if isinstance(v, list) else v + 1e-3})
    assert golden.differences(moved, want)


def test_a_failing_step_search_is_an_internal_error_refusal_not_a_crash(monkeypatch):
    import doorloc.vision.locate as L

    name, cell, door, img = next(c for c in golden.all_cases() if c[0] == "grid/img_0040.png")

    def broken(*a, **k):
        raise RuntimeError("step finder bug")

    monkeypatch.setattr(L, "coarse_edges", broken)
    r = L.locate(img, cell, door, image_name=name)
    assert not r.ok and r.error_code == "internal_error" and "step finder bug" in r.error
