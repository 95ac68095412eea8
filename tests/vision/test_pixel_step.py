"""The blurred-step pixel model evaluated near the edges only equals its evaluation on every pixel."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import ndtr

from doorloc.vision.edges import _pixel_step, _StepPixels


def _dense(bounds: np.ndarray, e: np.ndarray, sigma: float):
    """The model on every boundary (what :func:`_pixel_step` computed before it skipped the tails)."""
    y = bounds[None, :] - e[:, None]
    u = y / sigma
    Phi = ndtr(u)
    phi = np.exp(-0.5 * u * u) / math.sqrt(2.0 * math.pi)
    G = y * Phi + sigma * phi
    return np.diff(G, axis=1), np.diff(Phi, axis=1), np.diff(phi, axis=1)


@settings(max_examples=60, deadline=None)
@given(
    sigma=st.floats(0.05, 5.0),
    n_px=st.integers(4, 60),
    seed=st.integers(0, 2**31 - 1),
)
def test_tail_skipping_pixel_step_equals_the_dense_one(sigma, n_px, seed):
    rng = np.random.default_rng(seed)
    bounds = np.arange(n_px + 1, dtype=np.float64) - 0.5 + float(rng.integers(-5, 6))
    # edges inside, near and beyond the pixel row
    e = rng.uniform(bounds[0] - 3.0, bounds[-1] + 3.0, size=40)
    got = _pixel_step(bounds, e, sigma)
    want = _dense(bounds, e, sigma)
    for g, w in zip(got, want, strict=True):
        assert g.shape == w.shape
        np.testing.assert_allclose(g, w, rtol=0, atol=1e-14)


def test_tail_skipping_is_used_for_a_narrow_blur_and_not_for_a_wide_one():
    bounds = np.arange(41, dtype=np.float64) - 0.5
    e = np.array([10.3, 20.7])
    assert _StepPixels(bounds, e, 0.1).windowed  # a few boundaries per edge
    assert not _StepPixels(bounds, e, 3.0).windowed  # the tails cover the window: evaluated densely
    assert not _StepPixels(bounds, np.array([np.nan, 3.0]), 0.1).windowed  # NaN as the dense model gives it
