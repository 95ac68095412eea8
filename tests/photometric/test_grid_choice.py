"""A parameter the model check picks from a few values tried is reported with what is known of it.

The point spread's halo (``psf_tail``, ``psf_tail_px``) is chosen from :data:`TAIL_GRID`. Its report once
read ``psf_tail = 0.05 +- 6.9e-18`` and ``psf_tail_px = 6 +- nan`` on OpenCV's photographs: every fold
had picked the same grid point, and the spread of identical choices is no measurement of the value.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from doorloc.photometric.check import TAIL_GRID, grid_choice

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
