"""Parameters the model check reports carry a 1-sigma that says what is known of them, never 0 or NaN.

The point spread's halo (``psf_tail``, ``psf_tail_px``) is chosen from :data:`TAIL_GRID`. Its report once
read ``psf_tail = 0.05 +- 6.9e-18`` and ``psf_tail_px = 6 +- nan`` on OpenCV's photographs: every fold
had picked the same grid point, and the spread of identical choices is no measurement of the value.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from doorloc.photometric.check import TAIL_GRID, FieldOffsets, grid_choice
from doorloc.photometric.profiles import FieldOffset

FRACTIONS = [t for t, _ in TAIL_GRID]
SCALES = [b for _, b in TAIL_GRID]


def test_folds_that_agree_give_the_grids_resolution_not_zero():
    frac = grid_choice(0.05, np.full(5, 0.05), FRACTIONS)
    assert math.isclose(frac["sigma"], 0.015)  # half the step to 0.02, the nearest other fraction tried
    assert frac["at_bound"] == 0.0
    scale = grid_choice(6.0, np.full(5, 6.0), SCALES)
    assert math.isclose(scale["sigma"], 1.5)
    assert scale["at_bound"] == 1.0  # the widest halo tried: the data may ask for a wider one


@given(st.lists(st.sampled_from(FRACTIONS), min_size=2, max_size=13))
def test_folds_that_disagree_give_at_least_their_jackknife(choices):
    per_fold = np.array(choices)
    value = float(np.median(per_fold))
    value = min(FRACTIONS, key=lambda g: abs(g - value))
    k = per_fold.size
    jackknife = math.sqrt((k - 1) / k * float(((per_fold - per_fold.mean()) ** 2).sum()))
    got = grid_choice(value, per_fold, FRACTIONS)
    assert got["sigma"] >= jackknife - 1e-15
    assert got["sigma"] > 0.0
    assert got["at_bound"] == float(value in (min(FRACTIONS), max(FRACTIONS)))


def _fields(rng: np.random.Generator, n: int, scatter: float, noise: float) -> FieldOffsets:
    own = [
        FieldOffset(
            *(np.array([0.0, 0.2]) + rng.normal(0, scatter, 2) + rng.normal(0, noise, 2)), noise, noise, 40
        )
        for _ in range(n)
    ]
    return FieldOffsets(own, np.zeros((n, 2)), (0.0, 0.0))


def test_the_fields_scatter_carries_a_sigma_that_covers_its_error():
    """Bouguet's report read ``field_offset_scatter_px = 0.012 +- nan``. The jackknife over photographs now
    gives it a sigma; over many drawn sets of 20 photographs (scatter 0.03 px, each photograph's own reading
    0.01 px) the scatter read lies within 2 of its sigmas of the truth 9 times in 10 (0.87-0.91 over 8-20
    photographs: a jackknife of a spread runs a little short, as a sample's spread does)."""
    rng = np.random.default_rng(5)
    within = []
    for _ in range(200):
        f = _fields(rng, 20, 0.03, 0.01)
        scatter, sigma = f.mean_and_scatter()[2], f.scatter_sigma()
        assert math.isfinite(sigma) and sigma > 0
        within.append(abs(scatter - 0.03) <= 2 * sigma)
    assert np.mean(within) >= 0.85, np.mean(within)
    assert math.isnan(_fields(rng, 2, 0.03, 0.01).scatter_sigma())  # two photographs: no jackknife
