"""Selection against priors, continuing forward selection and joint pairs, on linear stand-in forward models.

Each stand-in effect predicts ``value * signature`` (a fixed random error pattern per effect), so the
selection's logic is tested exactly and fast; the rendered cases are in test_plausible_causes.py.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from doorloc.cell import load_cell
from doorloc.modelcheck.catalogue import CATALOGUE, Effect, arris_variants, effect
from doorloc.modelcheck.fit import SelectionRules, select_effects
from doorloc.modelcheck.priors import DEFAULT_SIGMA, IMPLAUSIBLE_SIGMAS, priors_for

CELL = load_cell(Path(__file__).resolve().parents[2] / "fixtures" / "cell_thesis.yaml")
N = 30


class _Linear:
    """Stand-in predictor: each effect adds ``value * signature`` to the error rows."""

    def __init__(self, signatures: dict[str, np.ndarray]) -> None:
        self.signatures = signatures
        self.analytic = type("A", (), {"nominal": CELL})()
        self.tables: dict = {}

    def predict(
        self, effects: Sequence[Effect], values: Sequence[np.ndarray], rows: np.ndarray
    ) -> np.ndarray:
        out = np.zeros((len(rows), 4))
        for e, v in zip(effects, values, strict=True):
            out += float(v[0]) * self.signatures[e.name][rows]
        return out


def _effect(name: str) -> Effect:
    return replace(
        effect("camera_roll"), name=name, params=("v",), lower=(-50.0,), upper=(50.0,), step=(0.1,)
    )


def _penalty(sigmas: dict[str, float]):
    return lambda e, v: float(np.sum((np.asarray(v) / sigmas[e.name]) ** 2))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_cause_that_leaves_structure_is_kept_while_the_second_is_tried(seed):
    # two causes at once: the first alone takes away ~60 %, short of the 75 % a single cause needs; before,
    # the selection stopped there and answered nothing (camera pan + fixture depth answered `unexplained`)
    rng = np.random.default_rng(seed)
    sig = {n: rng.normal(size=(N, 4)) for n in ("a", "b", "c", "d")}
    errors = 10 * sig["a"] + 8 * sig["b"] + rng.normal(size=(N, 4))
    cat = [_effect(n) for n in sig]
    sel = select_effects(_Linear(sig), cat, errors, np.ones(4), np.arange(N))
    assert sorted(sel.chosen.names) == ["a", "b"], sel.steps
    assert sel.steps[0]["provisional"] and not sel.steps[0]["accepted"]
    assert sel.steps[1]["accepted"]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_overlapping_signatures_are_fitted_as_a_pair(seed):
    # a and b nearly cancel each other: neither alone explains much, together they explain all
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(N, 4))
    sig = {"a": base + 0.3 * rng.normal(size=(N, 4)), "b": -base, "c": rng.normal(size=(N, 4))}
    errors = 10 * sig["a"] + 10 * sig["b"] + 0.3 * rng.normal(size=(N, 4))
    sel = select_effects(_Linear(sig), [_effect(n) for n in sig], errors, np.ones(4), np.arange(N))
    assert sorted(sel.chosen.names) == ["a", "b"], sel.steps


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noise_alone_names_nothing(seed):
    rng = np.random.default_rng(seed)
    sig = {n: rng.normal(size=(N, 4)) for n in ("a", "b", "c", "d")}
    sel = select_effects(
        _Linear(sig), [_effect(n) for n in sig], rng.normal(size=(N, 4)), np.ones(4), np.arange(N)
    )
    assert sel.chosen.names == ()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_plausible_cause_beats_an_implausible_surrogate_that_fits_a_little_better(seed):
    # the surrogate's pattern is the data's exactly; the physical cause leaves a small part. Without priors
    # the surrogate wins (a 0.79 mm rounded arris answered as focal length -0.69 %, 14 calibration sigmas)
    rng = np.random.default_rng(seed)
    t = rng.normal(size=(N, 4))
    d = rng.normal(size=(N, 4))
    sig = {"physical": t, "surrogate": t + 0.05 * d}
    errors = 5 * (t + 0.05 * d) + 0.05 * rng.normal(size=(N, 4))
    cat = [_effect(n) for n in sig]
    rows, noise = np.arange(N), np.full(4, 0.05)
    no_prior = select_effects(_Linear(sig), cat, errors, noise, rows, SelectionRules(max_effects=1))
    assert no_prior.chosen.names == ("surrogate",)
    sel = select_effects(
        _Linear(sig),
        cat,
        errors,
        noise,
        rows,
        SelectionRules(max_effects=1),
        prior_penalty=_penalty({"physical": 3.0, "surrogate": 0.05}),
    )
    assert sel.chosen.names == ("physical",), sel.steps
    assert [c["cause"] for c in sel.considered] == ["physical", "surrogate"]
    assert sel.considered[1]["prior_chi2"] > IMPLAUSIBLE_SIGMAS**2


def test_every_catalogue_parameter_has_a_prior_from_the_calibration_where_it_carries_one():
    pr = priors_for(CELL, CATALOGUE)
    assert set(pr) == {e.name for e in CATALOGUE}
    for e in CATALOGUE:
        assert len(pr[e.name].sigma) == len(e.params) and min(pr[e.name].sigma) > 0
    assert pr["focal_length"].sigma == DEFAULT_SIGMA["focal_length"]
    # the thesis cell's distortion is all zero: never calibrated, so k1 is broad
    assert pr["radial_distortion"].sigma[0] >= 0.1
    names = ("fx", "fy", "cx", "cy", "k1")
    sd = np.array([1.678, 1.727, 3.0, 4.0, 0.002])  # 0.1 % of fx and fy, 3 and 4 px, k1 0.002
    cov = np.diag(sd**2)
    cell = replace(CELL, calibration_covariance=cov, calibration_covariance_names=names)
    pr = priors_for(cell, CATALOGUE)
    assert pr["focal_length"].sigma[0] == pytest.approx(0.1, rel=0.01)
    assert pr["focal_length"].source == "calibration covariance"
    assert pr["pixel_aspect"].sigma[0] == pytest.approx(0.1 * np.sqrt(2), rel=0.01)
    assert pr["radial_distortion"].sigma[0] == pytest.approx(0.002)
    # a principal point known to 4 px (cy) doubts the tilt by atan(4 / fy) on top of the mount's
    tilt = pr["camera_tilt"].sigma[0]
    assert tilt == pytest.approx(
        np.hypot(DEFAULT_SIGMA["camera_tilt"][0], np.degrees(np.arctan(4 / cell.camera.fy)))
    )
    # 0.7 % focal length against a 0.1 % calibration: implausible
    assert pr["focal_length"].sigmas_away([0.7]) > IMPLAUSIBLE_SIGMAS


def test_the_arris_comes_in_both_profiles_and_sharp_edges_have_none():
    variants = arris_variants(CELL)
    assert [v.variant for v in variants] == [CELL.default_door.arris_profile, "round"]
    assert {v.name for v in variants} == {"arris"} and len({v.key for v in variants}) == 2
    rounded = variants[1].apply(CELL, [0.4])
    assert rounded.default_door.arris_profile == "round" and rounded.default_door.arris_mm == pytest.approx(
        0.4
    )
    assert variants[1].apply(CELL, [0.0]) == CELL
