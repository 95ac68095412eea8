"""The blurred-step pixel model evaluated near the edges only equals its evaluation on every pixel, and the
normal CDF and density it evaluates there are scipy's."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import ndtr

from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS, _step_pixel_values, pixel_step


def _dense(bounds: np.ndarray, e: np.ndarray, sigma: float):
    """The model on every boundary (what :func:`pixel_step` computed before it skipped the tails)."""
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
    got = pixel_step(bounds, e, sigma)
    want = _dense(bounds, e, sigma)
    for g, w in zip(got, want, strict=True):
        assert g.shape == w.shape
        np.testing.assert_allclose(g, w, rtol=0, atol=1e-14)


def test_tail_skipping_is_used_for_a_narrow_blur_and_not_for_a_wide_one():
    bounds = np.arange(41, dtype=np.float64) - 0.5
    e = np.array([10.3, 20.7])

    def windowed(e: np.ndarray, sigma: float) -> bool:
        return _step_pixel_values(bounds, e, sigma, STEP_TAIL_SIGMAS)[3]

    assert windowed(e, 0.1)  # a few boundaries per edge
    assert not windowed(e, 3.0)  # the tails cover the window: evaluated densely
    assert not windowed(np.array([np.nan, 3.0]), 0.1)  # NaN as the dense model gives it


def test_normal_cdf_and_density_as_scipy_s_over_the_tail_cut():
    # sampling.normal_cdf_pdf (Cephes' erfc form sharing the density's exponential, what the step models
    # evaluate near every edge) against scipy.special.ndtr: within 2e-14 relative (the exponential's
    # argument rounded once) and an ulp of 1 absolute, over the +-10 sigma the models evaluate
    import numba

    from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS
    from doorloc.vision.sampling import normal_cdf_pdf

    @numba.njit
    def both(u):
        P, p = np.empty(u.size), np.empty(u.size)
        for i in range(u.size):
            P[i], p[i] = normal_cdf_pdf(u[i])
        return P, p

    cut = STEP_TAIL_SIGMAS
    u = np.concatenate(
        [np.linspace(-cut, cut, 400_001), np.random.default_rng(3).uniform(-cut, cut, 100_000), [0.0, -0.0]]
    )
    P, p = both(u)
    want = ndtr(u)
    assert np.all(np.abs(P - want) <= 2e-14 * want + 2.3e-16)
    np.testing.assert_allclose(p, np.exp(-0.5 * u * u) / math.sqrt(2.0 * math.pi), rtol=1e-15, atol=0)
    # the branches meet: |u| = 1 and sqrt(2) (|x| = 1/sqrt(2), 1) and 8 sqrt(2), either side
    edges = np.array([1.0, math.sqrt(2.0), 8.0 * math.sqrt(2.0)])
    near = np.concatenate([edges, np.nextafter(edges, 0.0), np.nextafter(edges, 20.0)])
    near = np.concatenate([near, -near])
    P, _ = both(near)
    assert np.all(np.abs(P - ndtr(near)) <= 2e-14 * ndtr(near) + 2.3e-16)
