"""The compiled kernels (doorloc.vision.jit) give the numbers of the code they stand for.

- the area estimate (edges._area_edges) against subpixel_edges' numpy branch, which a plane that is
  neither C- nor F-ordered still takes: the same arrays, bit for bit, on random images, 8- and 16-bit,
  with and without a response table, plateaus of 1-3 px, smoothed levels or not, profiles leaving the image;
- the joint line fit's loop (lines._irls) compiled against itself run by Python (numba's semantics: NaN,
  integer division, float32), and against a known answer with outliers;
- the texture term (texture.texture_bias: its mean profiles and closed form compiled), the plateau levels
  (response.plateau_levels) and the RANSAC line (lines.ransac_line) against their numpy versions
  (numpy_reference.py), bit for bit (RANSAC: the same inliers, the line to 1e-12 px); the transition
  width (transition.transition_width) to 1e-12 of itself (its sums add in another order);
- the plane map (metric.PlaneMap: rays to a cell plane and back) and the step fit (blurred_step.step_fit) against
  their numpy versions, bit for bit;
- the search region's polyline interpolation (region._interp_on_scans) against np.interp over the sorted
  points, bit for bit;
- the camera response's asymmetry measure (response_asymmetry.asymmetry: its normalised profiles and paired bins
  compiled) against its numpy version, bit for bit, at many phases and at one (the spline path);
- a line's tilt doubt from its residuals' structure (edge_texture.residual_structure_tilt: its block means
  compiled) against its numpy version, to rounding (the blocks are summed in order, not pairwise);
- the least finite value's index (response_asymmetry._least_index) against np.nanargmin;
- the in-place selection (jit.select_kth) against np.partition, numpy's pairwise sum (jit.pairwise_sum)
  against ndarray.sum, the running mean (response_asymmetry._running_mean_nearest) against uniform_filter1d;
- the JPEG block ratio (jpeg_blocks.block_artifact_ratio: its integer path compiled) against its numpy branch and
  the gate's per-line figures (quality.line_figures) against their numpy expressions, bit for bit;
- the arris strip fit's pixel terms (arris_strip.pixel_terms) and its linear solve
  (arris_strip.StripProblem.solve) against their numpy versions, to rounding (the normal CDF is not
  scipy's to the last ulp; the normal equations are summed in another order and are ill-conditioned: the
  coefficients to 1e-6 of their scale); its evaluation one candidate at a time (_StripProblem.evaluate)
  against those two, its Gauss-Newton loop (StripProblem.refine) against the loop as written in Python,
  bit for bit, and its per-bin means (arris_strip_kernels.bin_means) against numpy's, bit for bit; the
  arris lines' border fit (arris_lines._line_borders) against its numpy version, to 1e-8 px;
- the far-face fit's sums (far_face_kernels.far_face_sums, _far_face_misfit, far_face_start_costs: its steps'
  pixel values formed per scan line) against the (N, M) arrays of the dense step model they replaced, to
  rounding, and its Gauss-Newton loop (far_face_kernels.far_face_gauss_newton) against the loop as written in Python.
The blurred-step pixel model (blurred_step._step_pixel_values) and its normal CDF are held to their dense formula
and scipy in test_pixel_step.py.
The coarse step finder is held to the first finder bit for bit in test_coarse.py.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.vision import jit
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.edge_texture import residual_structure_tilt
from doorloc.vision.edges import subpixel_edges
from doorloc.vision.lines import _irls, _revoted, fit_rectangle_edges, ransac_line
from doorloc.vision.response import plateau_levels
from doorloc.vision.sampling import linearizing_lut
from doorloc.vision.texture import texture_bias
from doorloc.vision.transition import transition_width

_ref_spec = importlib.util.spec_from_file_location(
    "numpy_reference", Path(__file__).with_name("numpy_reference.py")
)
assert _ref_spec is not None and _ref_spec.loader is not None
reference = importlib.util.module_from_spec(_ref_spec)
_ref_spec.loader.exec_module(reference)


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
    # (from 5 px: the widest window, 6 + 3 px, then misses the border on at least 40 of 60 lines; from 3,
    # seed 1519 of the 8-bit rows left exactly half of them, and the count below failed)
    along = np.arange(h if axis == "col" else w)[:, None]
    edge = rng.uniform(5, 20) + 0.2 * np.arange(w if axis == "col" else h)[None, :]
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
    none = subpixel_edges(
        plane, axis, scan[:0], centre[:0], half, **kw
    )  # no scan line: the same empty arrays
    none_ref = subpixel_edges(_strided(plane), axis, scan[:0], centre[:0], half, **kw)
    for field in ("along", "step", "noise", "bright", "valid"):
        assert getattr(none, field).dtype == getattr(none_ref, field).dtype and getattr(none, field).size == 0
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
    # (math.hypot rounds differently compiled and in CPython, and nine re-weightings carry an ulp to a few
    # 1e-9 of the weights: compared at 1e-8 of each array's scale, since the points' coordinates along the
    # line are measured from the weighted centroid, which such weights move by that much of the lines'
    # length for every point alike; seed 4864 moved it 6.4e-9 px, 1e-7 relative for a point beside it)
    for a, b in zip(compiled[1:], python[1:], strict=True):
        scale = float(np.max(np.abs(b))) if np.size(b) else 0.0
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-8 * scale + 1e-12)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    votes=st.lists(st.floats(1e-3, 1e6) | st.just(0.0), min_size=3, max_size=3),
)
def test_direction_revote_compiled_as_run_by_python(seed, votes):
    rng = np.random.default_rng(seed)
    t, groups = _rect_points(rng, 20)
    P = np.concatenate([groups["reference"][0], groups["far"][0], groups["bottom"][0][:, ::-1] * [1, -1]])
    sizes = np.array([400, 400, 150], np.int64)
    starts = np.array([0, 400, 800], np.int64)
    w = rng.uniform(0.0, 1.0, len(P)) * (rng.uniform(size=len(P)) > 0.05)
    args = (P, starts, sizes, w, np.array(votes), float(t) + 1e-4)
    compiled, python = _revoted(*args), _revoted.py_func(*args)
    assert compiled[0] == python[0] == any(v > 0 for v in votes)
    for a, b in zip(compiled[1:], python[1:], strict=True):
        scale = float(np.max(np.abs(b))) if np.size(b) else 0.0
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * scale + 1e-12)


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
    jit.select_kth(y, k)
    assert y[k] == np.partition(x, k)[k]
    assert np.all(y[:k] <= y[k]) and np.all(y[k + 1 :] >= y[k])
    np.testing.assert_array_equal(np.sort(y), np.sort(x))


def test_compile_kernels_compiles_every_kernel_locate_uses():
    import doorloc.vision.locate  # noqa: F401  (defines them all)

    assert jit.compile_kernels() >= 5


def test_the_warm_up_s_shares_together_warm_every_kernel_once(monkeypatch):
    import doorloc.vision.locate  # noqa: F401  (defines them all)

    warmed: list[int] = []
    kernels = [(i, warmed.append) for i in range(11)] + [(99, None)]  # the last: only other kernels call it
    monkeypatch.setattr(jit, "_KERNELS", kernels)
    for part in range(3):
        assert jit.compile_kernels(part, 3) == 12
    assert sorted(warmed) == list(range(11))
    with pytest.raises(ValueError, match="part 3 of 3"):
        jit.compile_kernels(3, 3)


def test_the_warm_up_compiles_in_one_process_where_numba_has_no_disk_cache(monkeypatch):
    from doorloc.vision import warmup

    def no_pool(*args, **kwargs):
        raise AssertionError("processes started though no cache could hold what they compile")

    monkeypatch.setattr(warmup, "ProcessPoolExecutor", no_pool)
    monkeypatch.setattr(jit, "_KERNELS", [])
    monkeypatch.setattr(jit, "_UNCACHED", [object()])
    assert not jit.cached_on_disk()
    assert warmup._fill_cache(2) == 0


def test_the_warm_up_compiles_locate_s_kernels():
    from doorloc.vision.warmup import compile_locate_kernels

    assert compile_locate_kernels() >= 5


def _grain_edge(rng, sixteen: bool, axis: str, gamma: float, n_lines: int, plateau: int = 1):
    """A blurred edge beside wood-like grain (a random period and contrast), noise; its area-estimate samples."""
    top = 65535 if sixteen else 255
    n_along, n_scan = 120, 320
    along = np.arange(n_along)[:, None]
    edge = 60 + rng.uniform(-3, 3) + rng.uniform(-0.05, 0.05) * np.arange(n_scan)[None, :]
    grain = rng.uniform(0, 0.05) * np.sin(2 * np.pi * along / rng.uniform(3, 12) + rng.uniform(0, 6))
    blur = rng.uniform(0.4, 2.0)
    img = 0.3 + 0.4 / (1 + np.exp(-(along - edge) / blur)) + grain + rng.normal(0, 0.01, (n_along, n_scan))
    plane = np.clip(img * top, 0, top).astype(np.uint16 if sixteen else np.uint8)
    if axis == "row":
        plane = np.ascontiguousarray(plane.T)
    lut = linearizing_lut(plane.dtype, gamma)
    scan = np.sort(rng.choice(n_scan, n_lines, replace=False))
    centre = edge[0, scan] + rng.normal(0, 0.5, n_lines)
    smp = subpixel_edges(plane, axis, scan, centre, 4, plateau, 255.0 / top, level_smooth=5, lut=lut)
    return plane, smp, lut


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    sixteen=st.booleans(),
    gamma=st.sampled_from([1.0, 1.8]),
    plateau=st.integers(1, 3),
    axis=st.sampled_from(["col", "row"]),
    skip=st.integers(0, 6),
    side=st.sampled_from([-1, 1]),
    blur=st.sampled_from([None, None, 0.9]),
    n_lines=st.sampled_from([6, 40, 300]),
)
def test_texture_term_as_its_numpy_version(seed, sixteen, gamma, plateau, axis, skip, side, blur, n_lines):
    rng = np.random.default_rng(seed)
    plane, smp, lut = _grain_edge(rng, sixteen, axis, gamma, n_lines, plateau)
    mask = rng.uniform(size=n_lines) > 0.1
    kw = dict(lut=lut, blur_px=blur, door_skip_px=skip, door_side=side)
    got = texture_bias(plane, smp, mask, 4, plateau, **kw)
    want = reference.texture_bias(plane, smp, mask, 4, plateau, **kw)
    np.testing.assert_array_equal(
        [got.offset_sigma_px, got.tilt_sigma], [want.offset_sigma_px, want.tilt_sigma]
    )
    if n_lines >= 40:
        assert np.isfinite(got.offset_sigma_px)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    sixteen=st.booleans(),
    gamma=st.sampled_from([1.0, 2.2]),
    axis=st.sampled_from(["col", "row"]),
    n_lines=st.sampled_from([2, 5, 60, 300]),
    half=st.integers(2, 9),
    quiet=st.sampled_from([0, -1, 1]),
)
def test_transition_width_and_plateau_levels_as_their_numpy_versions(
    seed, sixteen, gamma, axis, n_lines, half, quiet
):
    rng = np.random.default_rng(seed)
    plane, smp, lut = _grain_edge(rng, sixteen, axis, gamma, n_lines)
    mask = rng.uniform(size=n_lines) > 0.1
    got, want = (
        transition_width(plane, smp, mask, half, lut, quiet_side=quiet),
        reference.transition_width(plane, smp, mask, half, lut, quiet_side=quiet),
    )
    np.testing.assert_allclose(got, want, rtol=1e-12)
    if n_lines >= 60:
        # a width, not garbage: finite, and an RMS over the window (|x| <= half + 1/2). (It was 0.3 < got <
        # 3.0, which the generator's own edges break: logistic scales up to 2 px have RMS widths up to
        # 3.6 px, and the grain inside the window moves the mean gradient's second moment both ways; over
        # 4000 draws at every half-window it read 0 to 0.62 of half + 1/2. Seed 9 read 3.04 px for a
        # scale of 1.86 px, whose RMS width is 3.39.)
        assert np.isfinite(got) and 0.0 <= got <= half + 0.5
    got_l, want_l = plateau_levels(plane, smp, mask, half), reference.plateau_levels(plane, smp, mask, half)
    np.testing.assert_array_equal(got_l, want_l)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(0, 200),
    outliers=st.floats(0.0, 0.7),
    tol=st.sampled_from([1.0, 3.0]),
)
def test_ransac_line_as_its_numpy_version(seed, n, outliers, tol):
    rng = np.random.default_rng(seed)
    scan = np.sort(rng.choice(2000, n, replace=False)).astype(float)
    along = 300 + rng.uniform(-0.1, 0.1) * scan + rng.normal(0, 0.5, n)
    bad = rng.uniform(size=n) < outliers
    along[bad] += rng.uniform(-50, 50, int(bad.sum()))
    got, want = ransac_line(scan, along, tol), reference.ransac_line(scan, along, tol)
    assert (got is None) == (want is None)
    if got is not None and want is not None:
        np.testing.assert_array_equal(got.inliers, want.inliers)
        np.testing.assert_allclose([got.a, got.b], [want.a, want.b], rtol=0, atol=1e-12)


@pytest.mark.parametrize("distorted", [False, True])
@pytest.mark.parametrize("depth_y", [0.0, 31.5, -400.0])
def test_plane_map_as_its_numpy_version(distorted, depth_y):
    from doorloc.calib.camera import CameraModel, Extrinsics, PosedCamera
    from doorloc.vision.metric import PlaneMap

    cam = CameraModel.from_values(
        [[1400, 0, 960], [0, 1402, 540], [0, 0, 1]],
        [-0.08, 0.02, 0.001, -0.0005, 0.0] if distorted else [0, 0, 0, 0, 0],
        (1920, 1080),
    )
    m = PlaneMap(PosedCamera(cam, Extrinsics([1.5, 0.1, -0.05], [-20.0, 15.0, 600.0])), depth_y)
    uv = np.random.default_rng(3).uniform([-50, -50], [1970, 1130], (400, 2))
    xz = m.to_plane(uv)
    np.testing.assert_array_equal(xz, reference.plane_map_to_plane(m, uv))
    ok = xz[np.isfinite(xz[:, 0])]
    assert ok.shape[0] > 100
    np.testing.assert_array_equal(m.to_image(ok), reference.plane_map_to_image(m, ok))
    np.testing.assert_allclose(m.to_image(ok), uv[np.isfinite(xz[:, 0])], atol=1e-6)


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(0, 60),
    decreasing=st.booleans(),
    scan_is_u=st.booleans(),
    spoil=st.sampled_from(["none", "nan", "repeat", "shuffle"]),
    layout=st.sampled_from(["C", "F", "strided"]),
)
def test_polyline_interpolation_as_np_interp_over_the_sorted_points(
    seed, n, decreasing, scan_is_u, spoil, layout
):
    # region._interp_on_scans: compiled for polylines monotonic in scan, sorted by numpy for the others;
    # either way np.interp's numbers on _sorted_polyline's points (NaN beyond the polyline)
    from doorloc.vision.region import _interp_monotonic, _interp_on_scans, _interp_sorted, _sorted_polyline

    rng = np.random.default_rng(seed)
    scan = np.cumsum(rng.uniform(0.01, 30.0, n)) + rng.uniform(-50, 50)
    scan = scan[::-1] if decreasing else scan
    along = rng.normal(0, 100, n)
    uv = np.column_stack([scan, along] if scan_is_u else [along, scan])
    if n > 2 and spoil == "nan":
        uv[rng.integers(0, n), rng.integers(0, 2)] = np.nan
    elif n > 2 and spoil == "repeat":
        uv[1, 0 if scan_is_u else 1] = uv[0, 0 if scan_is_u else 1]
    elif n > 3 and spoil == "shuffle":
        uv = uv[rng.permutation(n)]
    uv = {"C": uv, "F": np.asfortranarray(uv), "strided": uv[::2]}[layout]
    axis = "col" if scan_is_u else "row"
    lo = int(np.floor(np.nanmin(scan))) - 5 if n else 0
    scans = np.arange(lo, lo + int(rng.integers(0, 500)))
    want = _interp_sorted(*_sorted_polyline(uv, axis), scans)
    np.testing.assert_array_equal(_interp_on_scans(uv, axis, scans), want)
    if spoil == "none":
        assert _interp_monotonic(uv, scan_is_u, scans)[1]  # the compiled path answered


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(3, 260),
    half=st.integers(4, 12),
    blocks=st.sampled_from([0, 3, 8]),
    one_phase=st.booleans(),
    spoil=st.sampled_from(["none", "flat_rows", "zeros", "shading", "grey_levels"]),
)
def test_response_asymmetry_as_its_numpy_version(seed, n, half, blocks, one_phase, spoil):
    # response_asymmetry.asymmetry (its normalisation and its paired bins compiled) against the numpy code, bit for
    # bit: blurred steps at random phases, exponents, plateaus and noise; rows without contrast, zero
    # levels (log 0), a shading tilt, 8-bit grey levels; with and without blocks; read at one phase (the spline path)
    from scipy.special import ndtr

    from doorloc.vision.response_asymmetry import Transitions, asymmetry

    rng = np.random.default_rng(seed)
    x = np.arange(-half, half + 1)[None, :] - rng.uniform(-0.5, 0.5, (n, 1))
    lo, hi = rng.uniform(0.02, 0.4), rng.uniform(0.5, 0.95)
    raw = (lo + (hi - lo) * ndtr(x / rng.uniform(0.4, 2.5))) ** (1 / rng.uniform(0.5, 2.5))
    raw = raw + rng.normal(0, rng.uniform(0, 0.02), raw.shape)
    if spoil == "flat_rows":
        raw[rng.uniform(size=n) < 0.3] = 0.4
    elif spoil == "zeros":
        raw[rng.uniform(size=raw.shape) < 0.05] = 0.0
    elif spoil == "shading":
        raw = raw * (1 + 0.02 * np.arange(raw.shape[1]))[None, :]
    raw = np.clip(raw, 0.0, 1.0)
    if spoil == "grey_levels":  # a camera's 8-bit levels: many pixels share each (the levels' table)
        raw = np.round(raw * 255.0) / 255.0
    t = Transitions(raw, np.zeros(n), one_phase=one_phase)
    gammas = np.geomspace(0.4, 5.0, 25)
    blk = rng.integers(0, blocks, n) if blocks else None
    want = reference.asymmetry(t, gammas, blk, blocks)
    np.testing.assert_array_equal(asymmetry(t, gammas, blk, blocks), want)
    if spoil == "none" and not one_phase and n >= 20 and half >= 6:
        assert np.isfinite(want).any()  # (the comparison saw numbers, not only NaN)


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    size=st.integers(1, 30),
    columns=st.integers(1, 12),
    holes=st.sampled_from([0.0, 0.1, 0.5, 1.0]),
)
def test_response_vertex_as_its_python_version(seed, size, columns, holes):
    # the compiled parabola vertex of the least asymmetry (one column, and each column of a blocks' table)
    # against the Python it replaced, bit for bit: noisy bowls on geometric grids, NaN holes (none, some,
    # all), flat and falling runs (no curvature: the grid's least value), minima at the ends
    import doorloc.vision.response_asymmetry as ra

    rng = np.random.default_rng(seed)
    grid = np.geomspace(rng.uniform(0.3, 1.5), rng.uniform(1.6, 6.0), size)
    x = np.log(grid)[:, None] - rng.uniform(np.log(grid[0]) - 0.5, np.log(grid[-1]) + 0.5, columns)[None, :]
    table = x**2 * rng.uniform(0.01, 2.0, columns) + rng.normal(0, rng.uniform(0, 0.3), (size, columns))
    table[:, rng.uniform(size=columns) < 0.2] = 1.0  # flat
    table[rng.uniform(size=table.shape) < holes] = np.nan
    want = np.array([reference.vertex(grid, table[:, k]) for k in range(columns)])
    np.testing.assert_array_equal(ra._vertices(grid, table), want)
    np.testing.assert_array_equal([ra._vertex(grid, np.ascontiguousarray(c)) for c in table.T], want)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_response_asymmetry_same_through_either_levels_index(seed, monkeypatch):
    # Transitions.levels indexes its levels with 16 bits where they allow, else with numpy's own index:
    # the asymmetry and the skew are the same numbers through either (8-bit grey levels, blocks, both paths)
    import doorloc.vision.response_asymmetry as ra

    rng = np.random.default_rng(seed)
    raw = np.round(rng.uniform(0.05, 0.95, (60, 15)) * 255.0) / 255.0
    raw.sort(axis=1)
    off = rng.uniform(-8.0, -6.0, 60)
    gammas, blk = np.geomspace(0.4, 5.0, 25), rng.integers(0, 4, 60)
    narrow = [ra.Transitions(raw, off, one_phase=p) for p in (False, True)]
    assert all(t.levels[1].dtype == np.uint16 for t in narrow)  # (cached: made before the patch)
    monkeypatch.setattr(ra, "_INDEX_LEVELS", 0)
    wide = [ra.Transitions(raw, off, one_phase=p) for p in (False, True)]
    for a, b in zip(narrow, wide, strict=True):
        assert b.levels[1].dtype == np.intp
        want = ra.asymmetry(b, gammas, blk, 4)
        assert np.isfinite(want).any()
        np.testing.assert_array_equal(ra.asymmetry(a, gammas, blk, 4), want)
        assert ra.transition_skew_px(a, slice(None), 2.2) == ra.transition_skew_px(b, slice(None), 2.2)


@pytest.mark.parametrize("seed", range(6))
def test_least_asymmetric_as_its_grids_read_in_full(seed):
    # least_asymmetric reads its finer grids' two ends from the grid's values instead of again: the exponents
    # (the least and, undithered, the other minima) are those of every finer grid read in full
    from scipy.special import ndtr

    import doorloc.vision.response_asymmetry as ra

    rng = np.random.default_rng(seed)
    n = 120
    x = np.arange(-7, 8)[None, :] - rng.uniform(-0.5, 0.5, (n, 1))
    lo, hi = rng.uniform(0.05, 0.3), rng.uniform(0.6, 0.95)
    raw = (lo + (hi - lo) * ndtr(x / rng.uniform(0.6, 2.0))) ** (1 / rng.uniform(0.6, 2.6))
    raw = np.clip(np.round((raw + rng.normal(0, 0.004, raw.shape)) * 255.0) / 255.0, 0.0, 1.0)
    grid = ra._RANGE_GRID

    def in_full(t: ra.Transitions, i: int) -> float:
        fine = np.geomspace(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)], 9)
        return ra._vertex(fine, ra.asymmetry(t, fine))

    for dithered in (True, False):
        t = ra.Transitions(raw, -7.0 - x[:, 0] + np.arange(-7, 8).mean(), dithered=dithered)
        a = ra.asymmetry(t, grid)

        best, others = ra.least_asymmetric(t, grid)
        assert np.isfinite(best) and best == in_full(t, int(np.nanargmin(a)))
        assert all(g in {in_full(t, j) for j in range(1, grid.size - 1)} for g in others)


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(0, 3000), size=st.integers(1, 17))
def test_pairwise_sum_and_running_mean_as_numpy_and_scipy(seed, n, size):
    from scipy.ndimage import uniform_filter1d

    from doorloc.vision.response_asymmetry import _running_mean_nearest

    rng = np.random.default_rng(seed)
    a = rng.normal(size=n) * np.exp(rng.normal(0, 4, n))
    lo = int(rng.integers(0, n + 1))
    assert jit.pairwise_sum(a, lo, n - lo) == a[lo:].sum()
    if n >= size:
        np.testing.assert_array_equal(
            _running_mean_nearest(a, size), uniform_filter1d(a, size, mode="nearest")
        )


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(1, 300),
    h=st.integers(3, 12),
    blur=st.floats(0.05, 2.5),
    noise=st.sampled_from([0.0, 2.0, 20.0]),
    flat=st.booleans(),
)
def test_step_fit_as_its_numpy_version(seed, n, h, blur, noise, flat):
    # blurred_step.step_fit (its Gauss-Newton rows compiled) against the numpy loop over the same pixel model,
    # bit for bit: noisy and clean steps, a profile without a step (its determinant 0: no move)
    from doorloc.vision.blurred_step import pixel_step, step_fit

    rng = np.random.default_rng(seed)
    bounds = np.arange(-h, h + 2, dtype=np.float64) - 0.5
    e0 = rng.uniform(-0.5, 0.5, n)
    C, _, _ = pixel_step(bounds, e0 + rng.normal(0, 0.2, n), blur)
    lo, hi = rng.uniform(10, 80, n), rng.uniform(120, 240, n)
    vals = lo[:, None] + (hi - lo)[:, None] * C + rng.normal(0, noise + 1e-9, C.shape)
    if flat:
        vals[0] = 50.0
    want = reference.step_fit(vals, e0, bounds, blur)
    np.testing.assert_array_equal(step_fit(vals, e0, bounds, blur), want)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    sixteen=st.booleans(),
    blocky=st.booleans(),
    noise=st.sampled_from([0.0, 0.6, 4.0]),
    centre=st.tuples(st.floats(-20, 420), st.floats(-20, 320)),
    half=st.sampled_from([16, 40, 96]),
)
def test_block_ratio_as_its_numpy_version(seed, sixteen, blocky, noise, centre, half):
    # jpeg_blocks.block_artifact_ratio's integer path (compiled: exact sums, float32 means, medians by selection)
    # against its numpy branch, which a float plane of the same levels takes, bit for bit: with and without
    # 8x8 block steps, at crops that the image's border cuts, 8- and 16-bit
    from doorloc.vision.jpeg_blocks import block_artifact_ratio

    rng = np.random.default_rng(seed)
    top = 65535 if sixteen else 255
    img = rng.uniform(0.2, 0.8) + 0.1 * np.sin(np.arange(400)[None, :] / rng.uniform(5, 40))
    img = np.repeat(img, 300, axis=0) + rng.normal(0, noise / 255, (300, 400))
    if blocky:  # a level per 8x8 block on top
        img = img + np.kron(rng.normal(0, 0.01, (38, 50)), np.ones((8, 8)))[:300, :400]
    plane = np.clip(img * top, 0, top).astype(np.uint16 if sixteen else np.uint8)
    s8 = 255.0 / top
    got = block_artifact_ratio(plane, np.array(centre), half=half, scale_to_8bit=s8)
    want = block_artifact_ratio(plane.astype(np.float32), np.array(centre), half=half, scale_to_8bit=s8)
    np.testing.assert_array_equal(got, want)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(1, 400),
    kept=st.sampled_from([0.0, 0.1, 0.8, 1.0]),
    nan=st.sampled_from([None, "step", "noise"]),
)
def test_line_figures_as_numpy(seed, n, kept, nan):
    # quality.line_figures (the gate's per-line figures compiled) against the numpy expressions it
    # replaced, bit for bit: no inliers, a few, all; a NaN among the inliers' steps or noise figures
    from doorloc.vision.quality import line_figures
    from doorloc.vision.sampling import median

    rng = np.random.default_rng(seed)
    w = np.where(rng.uniform(size=n) < kept, rng.uniform(0.1, 1.0, n), 0.0)
    res = rng.normal(0, 0.05, n)
    step = rng.normal(0, 60, n)
    noise = rng.uniform(0, 3, n).astype(np.float32)
    inl = w > 0
    if nan is not None and inl.any():
        (step if nan == "step" else noise)[np.flatnonzero(inl)[-1]] = np.nan
    got = line_figures(w, res, step, noise)
    n_i = int(inl.sum())
    want = (
        (n_i, float((res[inl] * res[inl]).sum()) / n_i, median(np.abs(step[inl])), median(noise[inl]))
        if n_i
        else (0, np.nan, 0.0, np.nan)
    )
    assert got[0] == want[0]
    np.testing.assert_array_equal(np.array(got[1:]), np.array(want[1:]))


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n_cand=st.integers(1, 25),
    n_rows=st.integers(1, 8),
    n_cells=st.sampled_from([1, 4, 9]),
    width=st.integers(12, 48),
    one_blur=st.booleans(),
)
def test_strip_pixel_terms_as_their_numpy_version(seed, n_cand, n_rows, n_cells, width, one_blur):
    # arris_strip.pixel_terms (compiled, Gaussian terms near each boundary only) against the array formula
    # over scipy's ndtr: within a few ulps of the values (the C library's erfc is not scipy's), blurs
    # from a twentieth of a pixel to wider than the profile, one blur for every candidate or one each
    from doorloc.vision.arris_strip import pixel_terms as _pixel_terms

    rng = np.random.default_rng(seed)
    edges = np.arange(width + 1) - 0.5
    bounds = rng.uniform(-3, width + 3, (n_cand, n_rows, 1)) + np.sort(rng.uniform(0, 5, n_cells + 1))
    sigma = rng.uniform(0.05, 8.0, 1 if one_blur else n_cand)
    got = _pixel_terms(edges, bounds, sigma)
    want = reference.pixel_terms(edges, bounds, np.broadcast_to(sigma, (n_cand,)))
    for g, w in zip(got, want, strict=True):
        assert g.shape == w.shape
        np.testing.assert_allclose(g, w, rtol=0, atol=1e-13 * width)


def _strip_problem(rng, n_cells: int, bins: int, noise: float):
    """An arris strip problem (arris_strip.StripProblem) on 60 ramp-shaped strip profiles with noise."""
    from doorloc.vision.arris_strip import StripProblem as _StripProblem

    x = np.arange(36, dtype=float)
    outer, width = rng.uniform(14, 18, 60), rng.uniform(0.5, 6.0, 60)
    r = np.clip((x[None] - outer[:, None]) / width[:, None], 0, 1) * rng.uniform(0.3, 1.0)
    r = r + (x[None] > (outer + width)[:, None]) * (1 - r) + rng.normal(0, noise, r.shape)
    return _StripProblem(r, x, outer, width, n_cells, bins, noise)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n_cand=st.integers(1, 12),
    bins=st.integers(1, 8),
    n_cells=st.sampled_from([1, 4, 8]),
    noise=st.sampled_from([0.002, 0.02, 0.1]),
    jac=st.booleans(),
)
def test_strip_solve_as_its_numpy_version(seed, n_cand, bins, n_cells, noise, jac):
    # arris_strip.StripProblem.solve (compiled: the normal equations summed in vector lanes, solved by
    # elimination) against the batched matrix products it replaced: the misfit to 1e-12, the coefficients of
    # the (ill-conditioned) normal equations, the deficit and the derivatives to 1e-6 relative
    rng = np.random.default_rng(seed)
    prob = _strip_problem(rng, n_cells, bins, noise)
    tau = (np.arange(n_cells) + 0.5) / n_cells
    basis = (
        np.ones((n_cells, 1))
        if n_cells == 1
        else np.maximum(0.0, 1.0 - np.abs(tau[:, None] * 3 - np.arange(4)))
    )
    terms = prob.pixel_terms(rng.uniform(-2, 2, n_cand), rng.uniform(0.3, 2.0, n_cand))
    got = prob.solve(terms, basis, jac)
    chi2, coef, deficit, grad, hess = reference.strip_solve(prob, terms, basis, jac)
    np.testing.assert_allclose(got.chi2, chi2, rtol=1e-12)
    scale = np.abs(coef).max(axis=1, keepdims=True)
    np.testing.assert_allclose(got.coef / scale, coef / scale, rtol=0, atol=1e-6)
    np.testing.assert_allclose(got.deficit, deficit, rtol=1e-6, atol=1e-9)
    if jac:
        assert grad is not None and hess is not None and got.grad is not None and got.hess is not None
        gs = np.abs(grad).max() + np.abs(hess).max() * 1e-6
        np.testing.assert_allclose(got.grad, grad, rtol=1e-6, atol=1e-9 * gs)
        np.testing.assert_allclose(got.hess, hess, rtol=1e-6)
    else:
        assert got.grad is None and got.hess is None


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n_delta=st.integers(1, 12),
    one_blur=st.booleans(),
    bins=st.integers(1, 8),
    n_cells=st.sampled_from([1, 4, 8]),
    jac=st.booleans(),
)
def test_strip_evaluate_as_its_terms_then_solve(seed, n_delta, one_blur, bins, n_cells, jac):
    # arris_strip.StripProblem.evaluate (compiled one candidate at a time: arris_strip_kernels.strip_evaluate) against the
    # two kernels over all candidates (pixel_terms, then solve) that it stands for: bit for bit, a single
    # blur broadcast over the offsets as they broadcast it
    rng = np.random.default_rng(seed)
    prob = _strip_problem(rng, n_cells, bins, 0.02)
    basis = np.ones((n_cells, 1)) if n_cells == 1 else rng.uniform(0, 1, (n_cells, 3))
    delta = rng.uniform(-2, 2, n_delta)
    sigma = rng.uniform(0.01, 2.0, 1 if one_blur else n_delta)
    got = prob.evaluate(delta, sigma, basis, jac)
    want = prob.solve(prob.pixel_terms(delta, sigma), basis, jac)
    for field in ("chi2", "coef", "deficit", "grad", "hess"):
        a, b = getattr(got, field), getattr(want, field)
        if b is None:
            assert a is None
        else:
            np.testing.assert_array_equal(a, b)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    bins=st.integers(1, 8),
    n_cells=st.sampled_from([1, 4, 8]),
    n_basis=st.sampled_from([1, 2, 3]),
    noise=st.sampled_from([0.002, 0.02, 0.1]),
    start=st.floats(-3.0, 3.0),
    blur=st.sampled_from([0.02, 0.3, 1.0, 2.5]),
    n_iter=st.sampled_from([0, 1, 6, 12]),
)
def test_strip_refine_as_its_python_loop(seed, bins, n_cells, n_basis, noise, start, blur, n_iter):
    # arris_strip.StripProblem.refine (its Gauss-Newton loop compiled) against the loop as it was written in
    # Python over evaluate (numpy_reference.strip_refine), from starts off the answer by up to 3 px, blurs
    # below evaluate's floor to wider than the strip, and a loop stopped after 0 and 1 steps as well as run
    # out: bit for bit where the Python loop solves its steps as the kernel does (LAPACK's elimination with
    # its two updates fused, exactly: _lapack_solve2); with np.linalg.solve, the same to rounding, or where
    # rounding decides whether a last tiny step lowers the misfit, a point as converged (numpy's BLAS
    # kernels differ between processors; on numpy's wheels here they gave the same numbers, which the
    # golden cases hold)
    rng = np.random.default_rng(seed)
    prob = _strip_problem(rng, n_cells, bins, noise)
    basis = np.ones((n_cells, 1)) if n_basis == 1 else rng.uniform(0, 1, (n_cells, n_basis))
    got = prob.refine(start, blur, basis, n_iter=n_iter)
    want = reference.strip_refine(prob, start, blur, basis, n_iter=n_iter, solve=_lapack_solve2)
    assert got[:2] == want[:2]
    for field in ("chi2", "coef", "deficit", "grad", "hess"):
        np.testing.assert_array_equal(getattr(got[2], field), getattr(want[2], field))
    numpy_loop = reference.strip_refine(prob, start, blur, basis, n_iter=n_iter)
    np.testing.assert_allclose(got[:2], numpy_loop[:2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(got[2].chi2, numpy_loop[2].chi2, rtol=1e-9)


def _lapack_solve2(a: np.ndarray, g: np.ndarray) -> np.ndarray:
    """``np.linalg.solve`` of a 2x2 system as LAPACK's getrf / getrs take it (partial pivoting, the
    multiplier by the pivot's reciprocal), the right-hand side's two updates rounded once (exact rational
    arithmetic): what arris_strip_kernels.solve2x2 computes with LLVM's fma."""
    from fractions import Fraction

    def fma(x: float, y: float, z: float) -> float:
        return float(Fraction(x) * Fraction(y) + Fraction(z))

    (a00, a01), (a10, a11) = np.asarray(a, float).tolist()
    g0, g1 = np.asarray(g, float).tolist()
    if abs(a10) > abs(a00):
        a00, a01, a10, a11, g0, g1 = a10, a11, a00, a01, g1, g0
    if a00 == 0.0 or a11 - a10 * (1.0 / a00) * a01 == 0.0:
        raise np.linalg.LinAlgError("Singular matrix")
    l10 = a10 * (1.0 / a00)
    x1 = fma(-l10, g0, g1) / (a11 - l10 * a01)
    return np.array([fma(-a01, x1, g0) / a00, x1])


def test_strip_refine_solves_its_steps_as_lapack():
    # arris_strip_kernels.solve2x2 (the refine's damped 2x2 step) against LAPACK's elimination with its two
    # updates fused (_lapack_solve2) bit for bit, and against np.linalg.solve to rounding (bit for bit on
    # numpy's wheels here), on systems of every scale, symmetric or not, either row the pivot; an exact zero
    # pivot is named, where numpy raises
    from doorloc.vision.arris_strip_kernels import solve2x2

    rng = np.random.default_rng(7)
    for scale in (1e-9, 1e-3, 1.0, 1e4, 1e9):
        for _ in range(2000):
            a = rng.normal(size=(2, 2)) * scale * np.exp(rng.normal(size=(2, 2)) * 3)
            if rng.uniform() < 0.7:
                a[1, 0] = a[0, 1]
            g = rng.normal(size=2) * np.exp(rng.normal(size=2) * 3)
            x0, x1, singular = solve2x2(a[0, 0], a[0, 1], a[1, 0], a[1, 1], g[0], g[1])
            assert not singular
            assert (x0, x1) == tuple(_lapack_solve2(a, g))
            want = np.linalg.solve(a, g)
            tol = 1e-13 * np.linalg.cond(a) * np.abs(want).max()
            np.testing.assert_allclose((x0, x1), want, rtol=0, atol=tol)
    for a in ([[0.0, 1.0], [0.0, 2.0]], [[1.0, 2.0], [2.0, 4.0]]):
        with pytest.raises(np.linalg.LinAlgError):
            np.linalg.solve(a, [1.0, 1.0])
        assert solve2x2(a[0][0], a[0][1], a[1][0], a[1][1], 1.0, 1.0)[2]


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(1, 300),
    n_m=st.integers(4, 30),
    sigma=st.sampled_from([0.05, 0.3, 1.0, 2.5]),
    with_blur=st.booleans(),
    has_strip=st.booleans(),
)
def test_far_face_kernels_as_the_array_code(seed, n, n_m, sigma, with_blur, has_strip):
    # far_face_kernels.far_face_sums, _far_face_misfit and far_face_start_costs (the far-face fit's sums, compiled,
    # its steps' pixel values formed per scan line) against the model, residuals and derivatives formed as
    # (N, M) arrays from the dense step model (blurred_step.pixel_step), as subpixel_edges_far_face formed them
    # before: to rounding (the sums run in vector lanes; the Gaussian tails the kernels skip are < 1e-22)
    from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS, pixel_step
    from doorloc.vision.far_face import LEVEL_PRIOR_WEIGHT
    from doorloc.vision.far_face_kernels import _far_face_misfit, far_face_start_costs, far_face_sums

    rng = np.random.default_rng(seed)
    core = rng.uniform(0, 255, (n, n_m))
    A, D = rng.uniform(20, 80, n), rng.uniform(-150, 150, n)
    bounds = np.arange(n_m + 1.0) + rng.uniform(2.5, 5.5)
    e0 = rng.uniform(bounds[0] + 1, bounds[-1] - 1, n)
    e = e0 + rng.normal(0, 1.0, n)
    w0 = rng.uniform(-2.0, 6.0, n)
    band_slope = -rng.uniform(0.0, 0.9)
    strip = rng.uniform(0.2, 3.0, n) * has_strip
    lam, mu = rng.uniform(-0.5, 1.5), rng.uniform(-0.5, 0.5) * has_strip

    def steps(e):
        w_raw = w0 + band_slope * (e - e0)
        has_band = w_raw > 0
        pos = [e, e + np.where(has_band, w_raw, 0.0)] + ([e - strip] if has_strip else [])
        C, g, h = pixel_step(bounds, np.concatenate(pos), sigma)
        C0 = C[2 * n :] if has_strip else C[:n]
        return C[:n], C[n : 2 * n], C0, g, h, has_band

    C1, C2, C0, g, h, has_band = steps(e)
    Dc = D[:, None]
    m = A[:, None] + (lam * Dc) * C1 + ((1.0 - lam) * Dc) * C2
    J_mu = Dc * (C0 - C1)
    if has_strip:
        m = m + mu * J_mu
    r = core - m
    a1, a2 = (lam - mu) * Dc, (1.0 - lam) * Dc
    J_e = -a1 * g[:n] - a2 * g[n : 2 * n] * (1.0 + band_slope * has_band)[:, None]
    J_sig = a1 * h[:n] + a2 * h[n : 2 * n]
    if has_strip:
        J_e = J_e - (mu * Dc) * g[2 * n :]
        J_sig = J_sig + (mu * Dc) * h[2 * n :]
    J_lam = Dc * (C1 - C2)
    Jg = [J_lam, J_sig if with_blur else np.zeros_like(r)] + ([J_mu] if has_strip else [])
    args = (core, A, D, bounds, e, w0, e0, band_slope, sigma, STEP_TAIL_SIGMAS, strip, has_strip, lam, mu)
    h_ee, h_eg, b_e, H, b_g, rr = far_face_sums(*args, with_blur)

    def close(got, terms, axis=None):
        # a sum taken in another order differs by at most (count - 1) ulps of the sum of its terms' sizes
        # (1e-12 absolute: the tails the kernels skip change a term by < 1e-22 of its scale, ~1e5)
        want, size = np.sum(terms, axis=axis), np.sum(np.abs(terms), axis=axis)
        assert np.all(np.abs(got - want) <= 1e-11 * size + 1e-12), (got, want)

    close(h_ee, J_e * J_e, axis=1)  # (where its sum is >= 1e-12, its floor)
    close(b_e, J_e * r, axis=1)
    close(rr, r * r, axis=1)
    assert h_eg.shape == (n, len(Jg)) and H.shape == (len(Jg), len(Jg))
    for k, Jk in enumerate(Jg):
        close(h_eg[:, k], J_e * Jk, axis=1)
        close(b_g[k], Jk * r)
        for j, Jj in enumerate(Jg):
            close(H[k, j], Jk * Jj)
    misfit, info = _far_face_misfit(*args)
    close(misfit, r * r)
    close(info, J_lam * J_lam)

    # the start search: each common shift's cost with the band level solved, a strip at its prior level
    shifts = np.arange(-2.0, 2.25, 0.5)
    mu0 = mu
    for every in (1, 3):
        costs, lams = far_face_start_costs(
            core, A, D, bounds, e0, w0, band_slope, sigma, STEP_TAIL_SIGMAS, strip, has_strip, mu0,
            LEVEL_PRIOR_WEIGHT, shifts, every,
        )  # fmt: skip
        rows = slice(0, None, every)
        for s, shift in enumerate(shifts):
            C1, C2, C0, _, _, _ = steps(e0 + shift)
            J = (Dc * (C1 - C2))[rows]
            C2m = C2 + mu0 * (C0 - C1) if has_strip else C2
            r0 = (core - (A[:, None] + Dc * C2m))[rows]
            info = np.sum(J * J)
            pull = LEVEL_PRIOR_WEIGHT * info
            lam_s = (np.sum(J * r0) + pull * 0.5) / max(info + pull, 1e-12)
            # rounding, and the tails the kernel skips (< 1e-22 of D per term), which the level's floor
            # on its information (1e-12) magnifies where the band is far narrower than a pixel
            tails = 1e-21 * np.sum(np.abs(Dc[rows]) * (np.abs(r0) + np.abs(J) + 1.0)) * (1.0 + abs(lam_s))
            scale = (1e-11 * (np.sum(np.abs(J * r0)) + pull) + tails) / max(info + pull, 1e-12) + 1e-12
            assert abs(lams[s] - lam_s) <= scale + 1e-9 * abs(lam_s), (lams[s], lam_s)
            rs = r0 - J * lams[s]
            close(costs[s] - pull * (lams[s] - 0.5) ** 2, rs * rs)


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(1, 200),
    fit_blur=st.booleans(),
    has_strip=st.booleans(),
    noise=st.sampled_from([0.0, 0.5, 3.0]),
)
def test_far_face_gauss_newton_as_its_python_loop(seed, n, fit_blur, has_strip, noise):
    # far_face_kernels.far_face_gauss_newton (the far-face fit's iterations compiled: the loop, the Schur complement,
    # the step and its halvings) against the loop as it was written in Python over the same sums
    # (numpy_reference.far_face_gauss_newton), on profiles of the model itself with noise, started off the
    # answer: the same iterate to rounding, or, where rounding decides whether a last tiny step lowers the
    # cost, a point as converged (the loop's own step tolerance, 1e-4 px, and the cost to 1e-9)
    from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS, pixel_step
    from doorloc.vision.far_face import LEVEL_PRIOR_WEIGHT
    from doorloc.vision.far_face_kernels import far_face_gauss_newton

    rng = np.random.default_rng(seed)
    n_m = 24
    bounds = np.arange(n_m + 1.0) + 3.5
    e_true = rng.uniform(10.0, 16.0) + 0.01 * np.arange(n) + rng.normal(0, 0.05, n)
    e0 = e_true + rng.normal(0, 0.3, n)
    w0 = np.full(n, rng.uniform(0.3, 5.0)) + rng.normal(0, 0.1, n)
    band_slope = -rng.uniform(0.0, 0.8)
    strip = np.full(n, rng.uniform(0.5, 3.0)) if has_strip else np.zeros(n)
    A, D = rng.uniform(20, 80, n), rng.uniform(50, 150, n) * rng.choice([-1.0, 1.0])
    lam_t, sig_t, mu_t = rng.uniform(0.1, 0.9), rng.uniform(0.3, 1.5), rng.uniform(-0.4, 0.4) * has_strip
    w = np.maximum(w0 + band_slope * (e_true - e0), 0.0)
    pos = [e_true, e_true + w] + ([e_true - strip] if has_strip else [])
    C, _, _ = pixel_step(bounds, np.concatenate(pos), sig_t)
    C1, C2 = C[:n], C[n : 2 * n]
    model = A[:, None] + (lam_t * D)[:, None] * C1 + ((1 - lam_t) * D)[:, None] * C2
    if has_strip:
        model += mu_t * D[:, None] * (C[2 * n :] - C1)
    core = model + rng.normal(0, noise, model.shape) if noise else model
    lo, hi = (-1.0, 2.0) if has_strip else (-math.inf, math.inf)
    args = (core, A, D, bounds, e0 + rng.normal(0, 0.2, n), w0, e0, band_slope, sig_t * rng.uniform(0.7, 1.3))
    args += (STEP_TAIL_SIGMAS, strip, has_strip, 0.5, 0.0, fit_blur, 10, LEVEL_PRIOR_WEIGHT, 0.3, 0.0, lo, hi)
    e_in = args[4].copy()
    # one step from the start (no later step for rounding to decide): the same iterate to rounding
    one = args[:15] + (1,) + args[16:]
    got, want = far_face_gauss_newton(*one), reference.far_face_gauss_newton(*one)
    np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got[1:5], want[1:5], rtol=1e-9, atol=1e-9)
    got = far_face_gauss_newton(*args)
    want = reference.far_face_gauss_newton(*args)
    np.testing.assert_array_equal(args[4], e_in)  # the start is not written over
    np.testing.assert_allclose(got[0], want[0], rtol=0, atol=2e-4)
    np.testing.assert_allclose(got[1:4], want[1:4], rtol=0, atol=2e-4)
    assert abs(got[4] - want[4]) <= 1e-9 * abs(want[4]) + 1e-9, (got[4], want[4])


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(1, 150),
    n_cells=st.integers(1, 6),
    blur=st.sampled_from([0.02, 0.4, 1.0, 2.5]),
    noise=st.sampled_from([0.0, 0.01, 0.2]),
    spoil=st.booleans(),
)
def test_line_borders_as_their_numpy_version(seed, n, n_cells, blur, noise, spoil):
    # arris_lines._line_borders (each line's strip border fitted, compiled per line) against the array code
    # it replaced (numpy_reference.line_borders): to rounding (the shape's sum over the strip's boundaries
    # was a matrix product, summed in BLAS's order), NaN where it gave NaN; lines with no contrast, a
    # border or width not finite, and a start off by up to 2 px among them
    from doorloc.vision.arris_lines import _line_borders

    rng = np.random.default_rng(seed)
    n_px = 28
    x = np.arange(n_px, dtype=float)
    outer = rng.uniform(6.0, 12.0, n)
    width = rng.uniform(0.5, 8.0, n)
    levels = np.sort(rng.uniform(-0.2, 1.3, n_cells))
    edges = np.concatenate([[0.0], levels, [1.0]])
    vals = np.zeros((n, n_px))
    for c in range(n_cells + 1):  # background 0 | cells | face 1, as area fractions of each pixel
        left = outer + width * c / n_cells if c else np.full(n, -np.inf)
        vals += (edges[c + 1] - edges[c]) * np.clip(x[None, :] + 0.5 - left[:, None], 0.0, 1.0)
    vals = (
        rng.uniform(10, 50, (n, 1)) + rng.uniform(40, 200, (n, 1)) * vals + rng.normal(0, noise, vals.shape)
    )
    start = outer + rng.uniform(-2.0, 2.0, n)
    if spoil and n > 3:
        vals[0] = 77.0  # no contrast
        start[1] = np.nan
        width[2] = np.inf
    got = _line_borders(vals, x, start, width, levels, blur)
    want = reference.line_borders(vals, x, start, width, levels, blur)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-8)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 1500), n_p=st.integers(1, 40), bins=st.integers(1, 12))
def test_strip_bin_means_as_numpy(seed, n, n_p, bins):
    # arris_strip_kernels.bin_means (the strip problem's per-bin counts and means, compiled) against the masks and
    # means it replaced: bit for bit (rows added in order, the 1-D means' sums pairwise, as numpy's)
    from doorloc.vision.arris_strip_kernels import bin_means

    rng = np.random.default_rng(seed)
    r = rng.normal(0, 1, (n, n_p)) * 10 ** rng.uniform(-3, 3)
    outer, width = rng.normal(5, 3, n), rng.uniform(0, 9, n)
    k = rng.integers(0, bins, n)
    used = np.unique(k)
    count, y, o, w = bin_means(r, outer, width, k, used)
    np.testing.assert_array_equal(count, [np.sum(k == b) for b in used])
    np.testing.assert_array_equal(y, np.stack([r[k == b].mean(axis=0) for b in used]))
    np.testing.assert_array_equal(o, [outer[k == b].mean() for b in used])
    np.testing.assert_array_equal(w, [width[k == b].mean() for b in used])


@settings(max_examples=100, deadline=None)
@given(
    values=st.lists(
        st.sampled_from([np.nan, np.inf, 0.5, 1.0, 2.0]) | st.floats(-1e3, 1e3), min_size=1, max_size=30
    ),
    column=st.booleans(),
)
def test_least_index_is_nanargmin_where_a_value_is_finite(values, column):
    # response._vertex's index of the least asymmetry (ties: the first; NaN skipped), on a contiguous
    # array and on a table's column as _least_asymmetric_blocks passes it
    from doorloc.vision.response_asymmetry import _least_index

    a = np.array(values, float)
    if column:
        table = np.zeros((a.size, 3))
        table[:, 1] = a
        a = table[:, 1]
    if np.any(np.isfinite(a)):
        assert _least_index(a) == np.nanargmin(a)
    else:
        assert _least_index(a) == -1


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(0, 900),
    reverse=st.booleans(),
    drop=st.floats(0.0, 0.5),
)
def test_residual_structure_tilt_as_its_numpy_version(seed, n, reverse, drop):
    rng = np.random.default_rng(seed)
    scan = np.arange(n)[::-1].copy() if reverse else np.arange(n)
    residual = rng.standard_normal(n) * rng.uniform(0.01, 1.0) + 0.3 * np.sin(
        scan / max(n, 1) * rng.uniform(0, 9)
    )
    residual[rng.uniform(size=n) < 0.02] = np.nan
    inliers = rng.uniform(size=n) >= drop
    samples = EdgeSamples(
        "col", scan, np.zeros(n), np.ones(n), np.zeros(n), np.zeros(n), np.ones(n, bool), np.ones(n, bool)
    )
    got = residual_structure_tilt(samples, residual, inliers)
    want = reference.residual_structure_tilt(scan, residual, inliers)
    if math.isnan(want):
        assert math.isnan(got)
    else:
        assert got == pytest.approx(want, rel=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(1, 80),
    width=st.integers(2, 31),
    top=st.sampled_from([0.0, 255.0, 65535.0]),
    noise=st.sampled_from([0.0, 0.01, 0.2]),
    thinned=st.booleans(),
)
def test_transition_skew_as_its_numpy_version(seed, n, width, top, noise, thinned):
    # the compiled skew against the numpy it replaced, bit for bit: blurred steps of either polarity at
    # every phase, flat profiles among them (fewer than 3 that step: NaN), noise that dips the mean
    # transition (its cumulative sum then falls back: np.searchsorted's bisection, not a scan), bins left
    # empty between filled ones (np.interp), 8- and 16-bit levels and free floats, a line's thinned offsets
    from scipy.special import ndtr

    import doorloc.vision.response_asymmetry as ra

    rng = np.random.default_rng(seed)
    off = rng.uniform(-width / 2 - 1, -width / 2 + 1, n) * rng.uniform(0.5, 2.0)
    edge = np.arange(width)[None, :] + off[:, None]
    lo, hi = rng.uniform(0.02, 0.5, n), rng.uniform(0.5, 0.98, n)
    flip = rng.uniform(size=n) < 0.3
    lo[flip], hi[flip] = hi[flip], lo[flip]
    lo[rng.uniform(size=n) < 0.1] = hi[0]  # flat: no step
    raw = lo[:, None] + (hi - lo)[:, None] * ndtr(edge / rng.uniform(0.3, 2.0))
    raw = np.clip(raw + rng.normal(0.0, noise, raw.shape), 0.0, 1.0)
    if top:
        raw = np.round(raw * top) / top
    if thinned:
        raw, off = np.repeat(raw, 2, axis=0)[::2], np.repeat(off, 2)[::2]
    t = ra.Transitions(raw, off, top=top)
    for g in (0.45, 1.0, 2.2, 4.7):
        want = reference.transition_skew_px(t, slice(None), g)
        got = ra.transition_skew_px(t, slice(None), g)
        assert got == want or (math.isnan(got) and math.isnan(want)), (g, got, want)
    rows = np.flatnonzero(rng.uniform(size=raw.shape[0]) < 0.7)
    want = reference.transition_skew_px(t, rows, 2.2)
    got = ra.transition_skew_px(t, rows, 2.2)
    assert got == want or (math.isnan(got) and math.isnan(want))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), thinned=st.booleans())
def test_plateau_misses_as_their_numpy_version(seed, thinned):
    # the compiled figures the response reading's plateau averaging is chosen by, against numpy (to
    # rounding: the kernel sums in its own order): noisy, quantised and grain-striped plateaus, whole
    # and thinned (strided) profiles; it fails on a miss taken against a mean that includes the line
    import doorloc.vision.response_plateaus as rp

    rng = np.random.default_rng(seed)
    n, width = int(rng.integers(17, 300)), int(rng.integers(8, 31))
    raw = rng.uniform(0.1, 0.9, (n, 1)) * np.ones((n, width))
    raw[:, width // 2 :] += (
        0.1 * (rng.uniform() < 0.5) * np.sin(np.arange(n) / rng.uniform(2.0, 8.0))[:, None]
    )
    raw += rng.normal(0.0, float(np.exp(rng.uniform(np.log(1e-4), np.log(0.02)))), raw.shape)
    if rng.uniform() < 0.3:
        raw = np.round(raw * 255.0) / 255.0
    if thinned:
        raw = raw[:: int(rng.integers(2, 4))]
    rounding = 1.0 / (12.0 * 255.0**2)
    want = reference.plateau_misses(raw, rounding, rp._ROWS_AVERAGED)
    got = rp._plateau_misses(raw, rp.RESPONSE_PLATEAU_PX, rounding, rp._ROWS_AVERAGED)
    np.testing.assert_allclose(got[0], want[0], rtol=1e-12)
    np.testing.assert_allclose(got[1], want[1], rtol=1e-9, atol=1e-18)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), top=st.sampled_from([255.0, 65535.0]))
def test_plateau_scatter_as_its_numpy_version(seed, top):
    # the compiled median scatter of the profiles' end pixels (whether noise dithers the rounding) against
    # the numpy it replaced, bit for bit: odd and even counts of profiles, flat and noisy plateaus, whole grey
    # levels and the full-scale float values between them (ten draws an example: a sum taken in another
    # order differs in its last bit on about one draw in ten)
    import doorloc.vision.response_asymmetry as ra

    rng = np.random.default_rng(seed)
    for _ in range(10):
        n, width = int(rng.integers(1, 90)), int(rng.integers(6, 31))
        noise = float(np.exp(rng.uniform(np.log(1e-4), np.log(0.1)))) * (rng.uniform() < 0.9)
        raw = np.clip(rng.uniform(0.1, 0.9, (n, 1)) + rng.normal(0.0, noise, (n, width)), 0.0, 1.0)
        if rng.uniform() < 0.3:
            raw = np.round(raw * top) / top
        want = reference.plateau_scatter(raw)
        assert ra._plateau_scatter(raw, ra.RESPONSE_PLATEAU_PX) == want
        assert ra.dithered(raw, top) == (want * top >= ra.DITHERING_NOISE_LEVELS)
