"""The plateau levels of an edge are averaged along it only where the surface beside it is uniform along it
(:func:`doorloc.vision.plateau_levels.level_smoothing`): texture across an edge (wood grain at a door's bottom end)
keeps each scan line's own level."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from doorloc.vision.edges import subpixel_edges
from doorloc.vision.plateau_levels import level_smoothing


def _striped_step(
    n_cols: int, edge_v: float, low: float, high: float, stripes: tuple[float, float, float], blur: float
) -> np.ndarray:
    """Columns with a horizontal step at row ``edge_v`` (dark above, bright below), the bright side striped
    across the edge: ``high (1 + c sin(2 pi u / period + phase))`` for ``stripes = (c, period, phase)``;
    box-filtered by the pixels, then blurred."""
    import cv2

    c, period, phase = stripes
    u = np.arange(n_cols)
    v = np.arange(60)[:, None]
    bright = high * (1.0 + c * np.sin(2 * math.pi * u / period + phase))[None, :]
    frac = np.clip(v + 0.5 - edge_v, 0.0, 1.0)
    img = low + (bright - low) * frac
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur, borderType=cv2.BORDER_REFLECT)
    return img


def _grey(img: np.ndarray, noise: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(np.rint(img + rng.normal(0.0, noise, img.shape)), 0, 255).astype(np.uint8)


@settings(max_examples=30, deadline=None)
@given(
    contrast=st.floats(0.10, 0.25),
    period=st.floats(15.0, 40.0),
    phase=st.floats(0.0, 2 * math.pi),
    edge_v=st.floats(28.0, 32.0),
    blur=st.floats(0.7, 1.5),
    noise=st.floats(0.0, 1.5),
    seed=st.integers(0, 2**31 - 1),
)
# stripes of the shortest period: read as noise by second differences of the levels, which kept them
# averaged over 3 lines (0.103 px RMS where each line's own levels gave 0.080)
@example(contrast=0.25, period=15.0, phase=0.0, edge_v=28.5, blur=0.75, noise=0.75, seed=0)
def test_an_edge_with_texture_across_it_is_read_at_each_scan_line_s_own_levels(
    contrast, period, phase, edge_v, blur, noise, seed
):
    img = _grey(_striped_step(240, edge_v, 40.0, 120.0, (contrast, period, phase), blur), noise, seed)
    u = np.arange(240)
    kw = dict(plateau=1, scale_to_8bit=1.0)
    read = subpixel_edges(img, "col", u, np.full(u.size, edge_v + 0.3), 4, level_smooth=10, **kw)
    own = subpixel_edges(img, "col", u, np.full(u.size, edge_v + 0.3), 4, level_smooth=0, **kw)
    inner = slice(15, -15)
    err = (read.along - edge_v)[inner]
    assert read.valid[inner].all()
    # the levels averaged over 21 scan lines had swung the points by up to a pixel with the stripes; each
    # line's own levels leave the noise's share only, and the choice is never worse than no averaging
    assert np.sqrt(np.mean(err**2)) <= max(0.1, 1.2 * np.sqrt(np.mean((own.along - edge_v)[inner] ** 2)))


def _levels_choice(img: np.ndarray, edge_v: float, half: int = 4) -> tuple[int, int]:
    """:func:`level_smoothing` (asked: 10 lines) of the two one-pixel plateaus of the columns of ``img`` read
    around row ``edge_v``: (above, below)."""
    c0 = int(round(edge_v + 0.3))
    A, B = img[c0 - half - 1].astype(np.float64), img[c0 + half + 1].astype(np.float64)
    step = float(np.median(np.abs(B - A)))
    yes = np.ones(img.shape[1], bool)
    start = np.full(img.shape[1], c0 - half - 1, np.int64)
    return tuple(int(level_smoothing(X, yes, start, 10, half, step, 1.0)) for X in (A, B))


@settings(max_examples=40, deadline=None)
@given(
    edge_v=st.floats(28.0, 32.0),
    blur=st.floats(0.5, 1.5),
    noise=st.floats(0.0, 4.0),
    shading=st.floats(-0.002, 0.002),
    seed=st.integers(0, 2**31 - 1),
)
def test_an_edge_uniform_along_it_keeps_its_averaging(edge_v, blur, noise, shading, seed):
    # a plain face, noise and a shading along the edge (grey levels rounded): averaged over all 10 lines
    img = _striped_step(300, edge_v, 40.0, 120.0, (0.0, 30.0, 0.0), blur)
    img = img * (1.0 + shading * np.arange(300))[None, :]
    assert _levels_choice(_grey(img, noise, seed), edge_v) == (10, 10)


@settings(max_examples=40, deadline=None)
@given(
    contrast=st.floats(0.10, 0.25),
    period=st.floats(12.0, 40.0),
    edge_v=st.floats(28.0, 32.0),
    noise=st.floats(0.0, 1.5),
    seed=st.integers(0, 2**31 - 1),
)
def test_an_edge_with_texture_across_it_is_averaged_less(contrast, period, edge_v, noise, seed):
    # (stripes much longer than the 21 lines averaged bias a level by little: 60 lines at 10-15 % and 1.5
    # grey levels of noise stay within the noise's share, and are kept averaged, as they may)
    img = _grey(_striped_step(300, edge_v, 40.0, 120.0, (contrast, period, 0.3), 1.0), noise, seed)
    above, below = _levels_choice(img, edge_v)
    assert above == 10  # the plain side keeps its averaging
    assert below < 10
    # ... and levels none of which lies inside the image give no reason to change it
    none = np.zeros(300, bool)
    assert level_smoothing(img[35].astype(np.float64), none, np.zeros(300, np.int64), 10, 4, 80.0, 1.0) == 10
