"""vision.coarse.coarse_edges (the fast step finder) answers exactly as the first finder (coarse_reference.py), bit for bit."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.vision import coarse
from doorloc.vision.locate import locate_steps

_spec = importlib.util.spec_from_file_location("locate_golden", Path(__file__).with_name("locate_golden.py"))
assert _spec is not None and _spec.loader is not None
golden = importlib.util.module_from_spec(_spec)
_ref_spec = importlib.util.spec_from_file_location(
    "coarse_reference", Path(__file__).with_name("coarse_reference.py")
)
assert _ref_spec is not None and _ref_spec.loader is not None
reference = importlib.util.module_from_spec(_ref_spec)
_ref_spec.loader.exec_module(reference)
sys.modules.setdefault("locate_golden", golden)
_spec.loader.exec_module(golden)


def _same(a, b) -> bool:
    return all(x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b, strict=True))


def test_every_search_of_the_fixtures_is_answered_identically():
    n = 0
    for _, cell, door, img in golden.all_cases():
        g = locate_steps(img, cell, door)
        try:
            q = next(g)
            while True:
                want = reference.coarse_edges(q.plane, **q.kwargs)
                assert _same(coarse.coarse_edges(q.plane, **q.kwargs), want)
                n += 1
                q = g.send(want)
        except StopIteration:
            pass
    assert n > 300


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    axis=st.sampled_from(["col", "row"]),
    polarity=st.sampled_from([-1, 0, 1]),
    half=st.integers(1, 4),
    stride=st.integers(1, 3),
    with_prefer=st.booleans(),
    deep=st.booleans(),
    frac=st.floats(0.05, 0.9),
)
def test_random_bands_near_and_beyond_the_border_are_answered_identically(
    seed, axis, polarity, half, stride, with_prefer, deep, frac
):
    rng = np.random.default_rng(seed)
    h, w = 60, 90
    img = (rng.integers(0, 65536 if deep else 256, (h, w))).astype(np.uint16 if deep else np.uint8)
    img[:, w // 2 :] //= 3  # a step, so that some rows have a clear edge
    n_scan, n_along = (w, h) if axis == "col" else (h, w)
    k = int(rng.integers(0, 12))
    scan = rng.integers(0, n_scan, k)
    lo = rng.integers(-5, n_along, k)
    hi = lo + rng.integers(0, 40, k)
    prefer = rng.uniform(0, n_along, k) if with_prefer else None
    if prefer is not None and k > 2:  # a NaN or infinite preference on one scan line
        prefer[int(rng.integers(0, k))] = np.nan if rng.random() < 0.5 else np.inf
    kw = dict(
        axis=axis,
        scan=scan,
        lo=lo,
        hi=hi,
        polarity=polarity,
        half=half,
        prefer=prefer,
        prefer_fraction=frac,
        stride=stride,
    )
    assert _same(coarse.coarse_edges(img, **kw), reference.coarse_edges(img, **kw))
