"""The sensor's clip level: the renderer stores light beyond it at that level, the model file validates it,
and an edge whose bright square is clipped is the one the censored fit re-places: unclipped edges stay
where they are, clipped ones come back to the board's lines (random blur, clip and exposure; seeds printed)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel
from doorloc.photometric.board_edges import measure_board_edges
from doorloc.photometric.clipping import (
    _best_x0,
    censored_blur_px,
    censored_offsets_px,
    clipped_lines,
    flat_topped_edges,
    unclipped_contrast,
)
from doorloc.photometric.fit import Photograph, place_edges, with_clip_references
from doorloc.photometric.model import CLIPPED_CONTRAST_MAX, PhotometricModel
from doorloc.photometric.profiles import edge_spread, fit_profiles
from doorloc.sim.boards import BOARD_BLACK, BOARD_WHITE, Checkerboard
from doorloc.sim.photometric import CameraRendering, render_photographed_board

CAMERA = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)


def _board(clip: float, exposure: float):
    rvec = np.array([0.1, -0.2, 0.05])
    tvec = -np.array([100.0, 62.5, 0.0]) + np.array([0.0, 0.0, 450.0])
    model = PhotometricModel(clip_level=clip)
    return render_photographed_board(
        CAMERA, Checkerboard(9, 6, 25.0), rvec, tvec, model, CameraRendering(0.8, exposure, 0.5), seed=3
    )


@pytest.mark.parametrize("clip", [0.55, 0.7, 0.9])
def test_renderer_stores_light_beyond_the_clip_at_the_clip(clip):
    rb = _board(clip, 1.05)  # the light squares reach 0.945 of full scale
    top = int(np.rint(clip * 255))
    assert rb.image.max() <= top
    # the clipped squares pile at the clip level
    assert (rb.image == top).mean() > 0.1


def test_only_edges_whose_bright_square_reaches_the_clip_count_as_clipped():
    rb = _board(0.7, 0.85)
    e = measure_board_edges(rb.image, rb.corners_px, 9, 6, 25.0, CAMERA)
    clipped = clipped_lines(e, 0.7)
    assert clipped.mean() > 0.9
    # the area estimator moves clipped edges towards the dark side
    assert np.nanmedian(e.offset_px[clipped]) < -0.05
    dim = _board(0.7, 0.6)
    e2 = measure_board_edges(dim.image, dim.corners_px, 9, 6, 25.0, CAMERA)
    assert not clipped_lines(e2, 0.7).any()
    assert abs(np.nanmedian(e2.offset_px)) < 0.02


def test_model_file_validates_the_clip_level():
    assert PhotometricModel.from_dict({"clip_level": 0.8}).clips
    assert not PhotometricModel().clips
    with pytest.raises(ValueError, match="clip_level"):
        PhotometricModel.from_dict({"clip_level": 1.2})
    g = PhotometricModel(clip_level=0.6).grey_from_light(np.array([0.3, 0.6, 0.9]))
    assert np.allclose(g, [0.3, 0.6, 0.6], atol=1e-3)


def test_a_response_far_from_the_cameras_is_costed_not_fatal():
    # a fit's search may try a power law of 4 on a linear camera's photographs, through which the board's
    # contrast reads 1:52000, more than a model holds: the clip's references take the most it holds
    image, e = _random_board(501, 1.0, 0.9, 0.8)
    photo = Photograph(image, e)
    far = PhotometricModel(gamma=4.0, clip_level=0.95)
    assert photo.unclipped_contrast(far) > CLIPPED_CONTRAST_MAX
    assert with_clip_references([photo], far).clipped_contrast == CLIPPED_CONTRAST_MAX
    # a sane response keeps the contrast it reads
    near = PhotometricModel(gamma=2.0, clip_level=0.95)
    assert with_clip_references([photo], near).clipped_contrast == pytest.approx(
        photo.unclipped_contrast(near)
    )
    place_edges(photo, with_clip_references([photo], far))  # and the edges are placed through it


def _random_board(seed: int, clip: float, exposure: float, blur: float):
    rng = np.random.default_rng(seed)
    rvec = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-0.2, 0.2)])
    tvec = np.array([-100.0, -62.5, 0.0]) + np.array(
        [rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(400, 520)]
    )
    rb = render_photographed_board(
        CAMERA,
        Checkerboard(9, 6, 25.0),
        rvec,
        tvec,
        PhotometricModel(clip_level=clip),
        CameraRendering(blur, exposure, float(rng.uniform(0.5, 1.5))),
        seed=seed,
    )
    return rb.image, measure_board_edges(rb.image, rb.corners_px, 9, 6, 25.0, CAMERA)


def _clipped_board(seed: int):
    """A board photographed with its light squares beyond a clip of 0.6-0.75 (blur 0.6-1.4 px): the blur,
    the clip and its measured edges."""
    rng = np.random.default_rng(seed)
    blur, clip = float(rng.uniform(0.6, 1.4)), float(rng.uniform(0.6, 0.75))
    exposure = float(rng.uniform(clip / BOARD_WHITE + 0.05, 1.05))
    print(f"seed {seed}: blur {blur:.2f} px, clip {clip:.3f}, exposure {exposure:.2f}")
    return blur, clip, _random_board(seed, clip, exposure, blur)[1]


@pytest.mark.parametrize("seed", [501, 502, 503])
def test_censored_fit_leaves_unclipped_edges_where_they_are(seed):
    rng = np.random.default_rng(seed)
    blur, exposure = float(rng.uniform(0.6, 1.4)), float(rng.uniform(0.55, 1.0))
    print(f"seed {seed}: blur {blur:.2f} px, exposure {exposure:.2f}")
    image, e = _random_board(seed, 1.0, exposure, blur)
    # no edge of an unclipped board is flat-topped (its plateaus carry the noise): a clip level among its
    # plateaus leaves every edge where the area estimator puts it
    assert not flat_topped_edges(e).any()
    photo = Photograph(image, e)
    high = float(np.nanpercentile(e.bright, 90) / 255.0)
    assert np.array_equal(
        place_edges(photo, PhotometricModel(clip_level=high)),
        place_edges(photo, PhotometricModel()),
        equal_nan=True,
    )
    # every line read as if clipped at its own plateau moves by little: the step from the board's contrast is
    # the plateau's up to the contrast's scatter over the edges (the larger of it and the plateau's step is
    # taken, so half the edges err towards the bright side by that scatter)
    lines = np.flatnonzero(np.isfinite(e.offset_px))
    contrast = unclipped_contrast(e, PhotometricModel(), np.zeros(e.n_edges, bool))
    assert abs(contrast - BOARD_WHITE / BOARD_BLACK) < 0.05 * BOARD_WHITE / BOARD_BLACK
    o = censored_offsets_px(e, lines, blur, contrast, PhotometricModel())
    assert abs(np.nanmedian(o) - np.nanmedian(e.offset_px[lines])) < 0.02


@pytest.mark.parametrize("seed", [601, 602, 603, 604])
def test_censored_fit_places_clipped_edges_with_the_blur_it_reads(seed):
    # the board's contrast from the camera's other photographs (here: the renderer's reflectances), the
    # blur read from the clipped lines themselves: the edges come back to the board's lines
    blur, clip, e = _clipped_board(seed)
    model = PhotometricModel(clip_level=clip)
    lines = np.flatnonzero(clipped_lines(e, clip) & np.isfinite(e.offset_px))
    assert lines.size > 0.8 * np.isfinite(e.offset_px).sum()
    plain = np.nanmedian(e.offset_px[lines])
    assert plain < -0.1
    contrast = BOARD_WHITE / BOARD_BLACK
    read = censored_blur_px(e, lines, contrast, model)
    assert abs(read - blur) < 0.05
    o = censored_offsets_px(e, lines, read, contrast, model)
    assert abs(np.nanmedian(o)) < 0.02, (plain, np.nanmedian(o))


def _censored_search_reference(d, y, exact, blur, amp, model):
    """The censored edge search one edge position at a time: the grid, then two parabola steps through the
    misfits at x0 -+ h (h the grid's spacing, then a twentieth of it)."""
    grid_px = np.linspace(-2.5, 2.5, 21)

    def sse(x0):
        r = y - amp[:, None] * edge_spread(d - x0[:, None], blur, model)
        return np.where(exact, r * r, np.maximum(r, 0.0) ** 2).sum(1)

    grid = np.stack([sse(np.full(y.shape[0], x)) for x in grid_px], 1)
    x0 = grid_px[np.clip(np.argmin(grid, 1), 1, grid_px.size - 2)]
    for h in (grid_px[1] - grid_px[0], 0.05 * (grid_px[1] - grid_px[0])):
        s0, s1, s2 = sse(x0 - h), sse(x0), sse(x0 + h)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = 0.5 * (s0 - s2) / (s0 - 2 * s1 + s2)
        x0 = x0 + h * np.where(np.isfinite(step) & (s0 - 2 * s1 + s2 > 0), np.clip(step, -1.0, 1.0), 0.0)
    return x0, sse(x0)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(4, 16), st.floats(0.3, 3.0), st.booleans(), st.integers(0, 2**31 - 1))
def test_the_censored_search_is_the_one_position_at_a_time_search_to_the_bit(n, length, blur, halo, seed):
    """The search evaluates all grid positions as one array and takes the first parabola step on the grid's
    own misfits (a board fit runs it hundreds of times a photograph): the same edges and misfits as one
    position at a time, with and without a halo, clipped samples and noise."""
    rng = np.random.default_rng(seed)
    model = PhotometricModel(psf_tail=0.05 if halo else 0.0, psf_tail_px=float(rng.uniform(0.5, 4)))
    d = np.arange(length) - length / 2 + rng.uniform(-1, 1, (n, 1))
    amp = rng.uniform(0.2, 1.0, n)
    y = amp[:, None] * edge_spread(d - rng.uniform(-2, 2, n)[:, None], blur, model) + rng.normal(
        0, 0.01, (n, length)
    )
    exact = y < 0.85 * amp[:, None] * rng.uniform(0.8, 1.2, (n, 1))
    for got, want in zip(
        _best_x0(d, y, exact, blur, amp, model),
        _censored_search_reference(d, y, exact, blur, amp, model),
        strict=True,
    ):
        assert np.array_equal(got, want, equal_nan=True)


@pytest.mark.parametrize("seed", [701, 702, 703])
def test_clipped_edges_profiles_are_drawn_with_the_clip(seed):
    # a clipped edge's profile under the model that clipped it: its levels fitted on the samples below the
    # clip (a censored fit) and every sample drawn clipped. Fitted with the clip's light as the bright
    # square's, these profiles were drawn no better than the plain model draws them (6.3-8.4 grey); drawn
    # right, they are left with the noise and the 8-bit rounding
    _, clip, e = _clipped_board(seed)
    assert clipped_lines(e, clip).mean() > 0.9
    keep = np.isfinite(e.offset_px)
    plain = fit_profiles(e, PhotometricModel(), keep).rms_over_windows()
    model = PhotometricModel(clip_level=float(np.rint(clip * 255) / 255))
    drawn = fit_profiles(e, model, keep).rms_over_windows()
    spread = e.plateau_spread_rms(3, keep)
    print(f"profile misfit plain {plain:.2f}, with the clip {drawn:.2f}, plateaus {spread:.2f} grey")
    assert drawn < 0.6 * plain and drawn < 1.5 * spread + 0.3
