"""The compiled kernels (doorloc.vision.jit) give the numbers of the code they stand for.

- the area estimate (edges._area_edges) against subpixel_edges' numpy branch, which a plane that is
  neither C- nor F-ordered still takes: the same arrays, bit for bit, on random images, 8- and 16-bit,
  with and without a response table, plateaus of 1-3 px, smoothed levels or not, profiles leaving the image;
- the joint line fit's loop (lines._irls) compiled against itself run by Python (numba's semantics: NaN,
  integer division, float32), and against a known answer with outliers;
- the in-place selection of the coarse finder (coarse._select) against np.partition.
The coarse step finder is held to the first finder bit for bit in test_coarse.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.vision import jit
from doorloc.vision.coarse import _select
from doorloc.vision.edges import linearizing_lut, subpixel_edges
from doorloc.vision.lines import _irls, fit_rectangle_edges


def _strided(plane: np.ndarray) -> np.ndarray:
    """The same pixels in a view that is neither C- nor F-contiguous (subpixel_edges' numpy branch)."""
    wide = np.zeros((plane.shape[0], plane.shape[1] + 3), plane.dtype)
    wide[:, : plane.shape[1]] = plane
    view = wide[:, : plane.shape[1]]
    assert not view.flags.c_contiguous and not view.flags.f_contiguous
    return view


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    sixteen=st.booleans(),
    gamma=st.sampled_from([1.0, 2.2]),
    plateau=st.integers(1, 3),
    level_smooth=st.sampled_from([0, 3, 10]),
    axis=st.sampled_from(["col", "row"]),
    half=st.integers(2, 6),
)
def test_area_kernel_gives_the_numpy_branch_numbers(seed, sixteen, gamma, plateau, level_smooth, axis, half):
    rng = np.random.default_rng(seed)
    h, w = 60, 70
    top = 65535 if sixteen else 255
    # a blurred step with noise, its place varying along the edge, near the image border on some lines
    along = np.arange(h if axis == "col" else w)[:, None]
    edge = rng.uniform(3, 20) + 0.2 * np.arange(w if axis == "col" else h)[None, :]
    prof = 0.2 + 0.6 / (1 + np.exp(-(along - edge) / rng.uniform(0.3, 2.0)))
    img = prof + rng.normal(0, 0.01, prof.shape)
    plane = np.clip(img * top, 0, top).astype(np.uint16 if sixteen else np.uint8)
    if axis == "row":
        plane = np.ascontiguousarray(plane.T)
    n_scan = plane.shape[1] if axis == "col" else plane.shape[0]
    scan = np.arange(n_scan)
    centre = edge[0] + rng.normal(0, 0.7, n_scan)
    centre[rng.integers(0, n_scan)] = np.nan
    lut = linearizing_lut(plane.dtype, gamma)
    kw = dict(plateau=plateau, scale_to_8bit=255.0 / top, level_smooth=level_smooth, lut=lut)
    fast = subpixel_edges(plane, axis, scan, centre, half, **kw)
    ref = subpixel_edges(_strided(plane), axis, scan, centre, half, **kw)
    assert np.count_nonzero(fast.valid) > n_scan // 2
    for field in ("along", "step", "noise", "bright", "valid"):
        a, b = getattr(fast, field), getattr(ref, field)
        assert a.dtype == b.dtype, field
        if field == "along":  # the window's float64 sum, in another order: an ulp or two
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12, err_msg=field)
        else:
            np.testing.assert_array_equal(a, b, err_msg=field)


def _rect_points(rng: np.random.Generator, n_out: int):
    t = np.radians(rng.uniform(-2, 2))
    c, s = np.cos(t), np.sin(t)
    z = np.linspace(5, 300, 400)
    x = np.linspace(5, 200, 150)
    ref = np.stack([2 - z * s, 3 + z * c], 1) + rng.normal(0, 0.01, (400, 2))
    far = np.stack([52 - z * s, 3 + z * c], 1) + rng.normal(0, 0.01, (400, 2))
    bot = np.stack([2 + x * c, 3 + x * s], 1) + rng.normal(0, 0.01, (150, 2))
    ref[rng.integers(0, 400, n_out)] += rng.uniform(-3, 3, (n_out, 2))
    return t, {"reference": (ref, False), "far": (far, False), "bottom": (bot, True)}


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n_out=st.integers(0, 80), offset_only=st.booleans())
def test_line_fit_loop_compiled_as_run_by_python(seed, n_out, offset_only):
    rng = np.random.default_rng(seed)
    _, groups = _rect_points(rng, n_out)
    P = np.concatenate([groups["reference"][0], groups["far"][0], groups["bottom"][0][:, ::-1] * [1, -1]])
    sizes = np.array([400, 400, 150], np.int64)
    starts = np.array([0, 400, 800], np.int64)
    mask0 = rng.uniform(size=len(P)) > 0.02
    votes = np.concatenate([np.ones(400), np.zeros(400) if offset_only else np.ones(400), np.ones(150)])
    args = (P, starts, sizes, mask0, votes, offset_only, 1e-4, 9, 512)
    compiled, python = _irls(*args), _irls.py_func(*args)
    assert compiled[0] == python[0] == 0
    # (math.hypot rounds differently compiled and in CPython, and nine re-weightings carry an ulp to ~1e-10)
    for a, b in zip(compiled[1:], python[1:], strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-9)


def test_line_fit_finds_the_rectangle_through_outliers_and_names_an_empty_line():
    rng = np.random.default_rng(5)
    t, groups = _rect_points(rng, 60)
    fit = fit_rectangle_edges(groups)
    assert fit.angle_rad == pytest.approx(t, abs=2e-5)
    assert fit.offsets["far"] - fit.offsets["reference"] == pytest.approx(50.0 * np.cos(t), abs=0.005)
    assert np.count_nonzero(fit.weights["reference"] == 0) >= 40  # the outliers are out
    no_bottom = {k: np.zeros(len(v[0])) if k == "bottom" else np.ones(len(v[0])) for k, v in groups.items()}
    with pytest.raises(ValueError, match="bottom"):
        fit_rectangle_edges(groups, init_weights=no_bottom)


@settings(max_examples=80, deadline=None)
@given(
    values=st.lists(
        st.sampled_from([0.0, 1.0, 2.5, 3.0, -1.0, 7.25]) | st.floats(-100, 100), min_size=1, max_size=60
    ),
    data=st.data(),
)
def test_select_puts_the_kth_smallest_in_place(values, data):
    x = np.array(values, np.float32)
    k = data.draw(st.integers(0, x.size - 1))
    y = x.copy()
    _select(y, k)
    assert y[k] == np.partition(x, k)[k]
    assert np.all(y[:k] <= y[k]) and np.all(y[k + 1 :] >= y[k])
    np.testing.assert_array_equal(np.sort(y), np.sort(x))


def test_compile_kernels_compiles_every_kernel_locate_uses():
    import doorloc.vision.locate  # noqa: F401  (defines them all)

    assert jit.compile_kernels() >= 5
