"""The camera exponents a door's rounded strips allow where no plain edge measures the response
(:mod:`doorloc.vision.strip_response`)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.vision.locate import locate
from doorloc.vision.strip_response import (
    ARC_RULED_OUT,
    GREY_EXPLAINS,
    INNER_STEPS,
    StripReadings,
    allowed_response_ends,
)

CELL = load_cell(Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml")


def _reader(misfit_at, shift_per_log=0.5):
    """A stand-in for the strips read again: the arcs' misfit over free ``misfit_at(gamma)``, and one line
    whose shift is linear in the log exponent (``shift_per_log`` px per unit of ln gamma from 1.5)."""
    calls = []

    def read(gammas, scores):
        calls.append(list(gammas))
        return StripReadings(
            {"reference": np.array([shift_per_log * math.log(g / 1.5) for g in gammas])},
            np.array([math.log(misfit_at(g)) if scores != "none" else math.nan for g in gammas]),
            math.log(misfit_at(1.5)) if scores == "all" else math.nan,
        )

    return read, calls


def test_exponents_fitted_alike_leave_the_factors_ends():
    read, calls = _reader(lambda g: 1.02)
    ends = allowed_response_ends(1.5, 2.2, read)
    assert ends.gammas == pytest.approx((3.0, 0.8))
    assert len(calls) == 1, "no inner reading where no end is ruled out"
    assert "alike" in ends.figure["unchanged_because"]


def test_a_ruled_out_end_moves_inwards_half_way_to_the_first_exponent_ruled_out():
    # misfit grows fast above 2.5: the upper end (1.5 * 2.2 = 3.3, brought to 3.0) ruled out, half its
    # reach (1.5 * 2.2 ** 0.5 = 2.22) allowed
    assert INNER_STEPS == (0.5,)
    read, calls = _reader(lambda g: 1.01 if g <= 2.5 else 1.01 * ARC_RULED_OUT * 1.2)
    ends = allowed_response_ends(1.5, 2.2, read)
    upper, lower = ends.gammas
    assert upper == pytest.approx(1.5 * 2.2**0.75)
    assert lower == pytest.approx(0.8), "the side whose end is allowed keeps it (1.5 / 2.2 brought to 0.8)"
    assert calls[1] == pytest.approx([1.5 * 2.2**0.5]), "inner readings on that side only"
    # the shift at the moved end: the strips read there (not interpolated between the readings at 0.5 and 1,
    # that one at 3.0, which here would say 0.5 * (0.5 * ln 2.2 ** 0.5 + 0.5 * ln 2))
    assert calls[2] == pytest.approx([upper]), "the moved end read where it lies"
    s_up, s_down = ends.shifts["reference"]
    assert s_up == pytest.approx(0.5 * math.log(upper / 1.5))
    assert s_down == pytest.approx(0.5 * math.log(0.8 / 1.5))
    assert ends.figure["allowed_gammas"] == pytest.approx([round(lower, 3), round(upper, 3)])


@pytest.mark.parametrize(
    ("why", "misfit_at"),
    [
        ("worse than another", lambda g: 1.6 if abs(g - 1.5) < 1e-9 else 1.01),  # the cell's own ruled out
        ("no matt arc", lambda g: 1.3 + (g - 1.5) ** 2),  # no arc explains the strips
        ("no rounded or chamfered strip", lambda g: math.nan),  # strips lost at an exponent
    ],
)
def test_no_evidence_keeps_the_factors_ends(why, misfit_at):
    read, _ = _reader(misfit_at)
    ends = allowed_response_ends(1.5, 2.2, read)
    assert ends.gammas == pytest.approx((3.0, 0.8))
    assert why in ends.figure["unchanged_because"]


def test_a_measured_response_is_not_scored():
    """A cell whose response was measured (factor 1.11) reads exponents 10 % apart, too near for the arcs to
    tell (one fitting better than the cell's would be the scores' noise): its ends are read, not scored."""
    read, calls = _reader(lambda g: 1.6 if abs(g - 1.5) < 1e-9 else 1.01)
    ends = allowed_response_ends(1.5, 1.11, read)
    assert ends.gammas == pytest.approx((1.5 * 1.11, 1.5 / 1.11))
    assert len(calls) == 1 and ends.figure == {}


def test_an_exponent_near_the_cells_fitting_better_disputes_nothing():
    """With a factor of 1.3 the upper end (1.95) is ruled out and half its reach (1.71, 1.14 times the
    cell's 1.5) fits best, 1.3 times better than the cell's: too near to say the cell is wrong."""
    misfit = {1.5: 1.3, 1.95: 1.8, 1.154: 1.1, 1.71: 1.0}
    read, _ = _reader(lambda g: misfit[min(misfit, key=lambda k: abs(k - g))])
    ends = allowed_response_ends(1.5, 1.3, read)
    assert "near the cell's" in ends.figure["unchanged_because"]
    assert "cell_disputed" not in ends.figure
    assert ends.gammas == pytest.approx((1.95, 1.5 / 1.3))


# A door of the arris bench's round set (bench_arris_range.py --sets round --seed 9109), its draw to the last
# digit: a 1.73 mm rounding lit from azimuth -41 deg, a camera of exponent 1.11, every edge an arris.
DOOR = DoorSize(900, 40.0, 2100, arris_mm=1.7328930979978872, arris_profile="round")
POSE = DoorPose(-1.2926494963581092, 1.8169845567940381, -0.4324862367041533)
EFFECTS = Effects(
    albedo_hinge=0.668685714423771,
    albedo_chamfer=0.9384358372407031,
    albedo_background=0.061124867388965845,
    light_ambient=0.38463735079700484,
    light_directional=0.14702320101078298,
    light_azimuth_deg=-40.76465354986796,
    light_elevation_deg=-24.023724591286694,
    grain_period_mm=6.592721060317301,
    arris_profile="round",
    blur_sigma_px=1.375415639419385,
    read_noise_dn=0.4058028629306262,
    gamma=1.1077562786689659,
)


@pytest.fixture(scope="module")
def image():
    return render_door(CELL, DOOR, POSE, effects=EFFECTS, seed=9109).image


def test_a_roundings_shading_narrows_the_unmeasured_responses_doubt(image):
    """Told its camera's exponent (not measured: the factor 2.2), the door was refused as uncertain (x 0.100
    mm, the response's doubt 0.092 mm of it, from the exponents 0.8 and 2.44); its strips read with 2.44
    fit no matt arc (3.5 times the free shading's misfit, 1.03 at the cell's), and the doubt spans the
    exponents they allow."""
    res = locate(image, dataclasses.replace(CELL, response_gamma=EFFECTS.gamma), DOOR)
    assert res.ok, res.error
    fig = res.diagnostics["response_from_strips"]
    lo, hi = fig["allowed_gammas"]
    assert 0.8 <= lo <= EFFECTS.gamma <= hi < 1.8
    assert res.diagnostics["arris_fit"]["reference"]["response_gammas"] == pytest.approx([hi, lo])
    assert abs(res.x_mm - POSE.x_mm) <= 2 * res.uncertainty.x_mm
    assert abs(res.z_mm - POSE.z_mm) <= 2 * res.uncertainty.z_mm


def test_a_cell_exponent_the_strips_rule_out_refuses_the_door(image):
    """The same door in a cell that says 2.40 (an sRGB camera assumed for a near-linear one): the strips
    read with 2.40 fit a matt arc three times worse than with 1.09. It had been answered 0.165 mm off in x
    at a sigma of 0.093; it is refused, the cell's exponent named."""
    res = locate(image, dataclasses.replace(CELL, response_gamma=2.40), DOOR)
    fig = res.diagnostics["response_from_strips"]
    assert "worse than another" in fig["unchanged_because"]
    assert fig["cell_disputed"]["cell_over_best"] > 2.0
    assert fig["cell_disputed"]["best_gamma"] < 1.5
    assert not res.ok and res.error_code == "uncertain"
    assert "camera.response_gamma 2.4" in res.error


def test_chamfers_that_no_reading_explains_rule_nothing_out():
    """A chamfered door's strips score in grey levels over the noise: where even the best reading misses
    the image by more than GREY_EXPLAINS times its noise (a strip the one-level model does not describe),
    a far worse end is not ruled out."""

    def read(gammas, scores):
        misfit = [GREY_EXPLAINS * 1.5 * (1.0 if g < 2.0 else 3.0) for g in gammas]
        return StripReadings(
            {"reference": np.zeros(len(gammas))},
            np.log(misfit),
            math.log(GREY_EXPLAINS * 1.5) if scores == "all" else math.nan,
            "chamfers",
        )

    ends = allowed_response_ends(1.5, 2.2, read)
    assert ends.gammas == pytest.approx((3.0, 0.8))
    assert "miss the image" in ends.figure["unchanged_because"]
    assert "chamfer_grey_misfit" in ends.figure and "arc_misfit_over_free" not in ends.figure


# A door of the arris bench's ambient set (bench_arris_range.py --sets ambient --seed 11105), its draw to the
# last digit: a 2.55 mm chamfer under ambient light alone, a camera of exponent 1.09, every edge an arris.
CHAMFERED = DoorSize(900, 50.0, 2100, arris_mm=2.553447208703535, arris_profile="chamfer")
CHAMFERED_POSE = DoorPose(5.6495405674138315, -5.8733033401188806, -0.953750803972651)
CHAMFERED_EFFECTS = Effects(
    albedo_hinge=0.879538901707407,
    albedo_chamfer=0.7488888389678632,
    albedo_background=0.0983060683912369,
    light_ambient=1.0422579437306956,
    light_directional=0.0,
    light_azimuth_deg=18.470360850836887,
    light_elevation_deg=23.500158479605112,
    grain_period_mm=7.871558505855033,
    arris_profile="chamfer",
    blur_sigma_px=1.5590877010808808,
    read_noise_dn=0.20434642471245723,
    gamma=1.08838528630626,
)


@pytest.fixture(scope="module")
def chamfered_image():
    return render_door(CELL, CHAMFERED, CHAMFERED_POSE, effects=CHAMFERED_EFFECTS, seed=11105).image


def test_a_chamfers_borders_narrow_the_unmeasured_responses_doubt(chamfered_image):
    """Told its camera's exponent (not measured: the factor 2.2), the door was refused as uncertain (x 0.103
    mm, the response's doubt 0.103 mm of it, from the exponents 0.8 and 2.39); read with 2.39 its chamfers'
    fitted profiles miss the image by 12.7 times its noise (1.04 with the camera's), with 0.8 by 1.47, and
    the doubt spans the exponents they allow."""
    res = locate(
        chamfered_image, dataclasses.replace(CELL, response_gamma=CHAMFERED_EFFECTS.gamma), CHAMFERED
    )
    assert res.ok, res.error
    fig = res.diagnostics["response_from_strips"]
    lo, hi = fig["allowed_gammas"]
    assert 0.8 < lo <= CHAMFERED_EFFECTS.gamma <= hi < 1.6
    assert min(fig["chamfer_grey_misfit"]) < 1.2, "the camera's exponent leaves about the noise"
    assert fig["gammas"][0] == 0.8 and fig["gammas"].count(0.8) == 1, (
        "the two reaches brought to 0.8: one reading"
    )
    assert res.uncertainty.x_mm < 0.06
    assert abs(res.x_mm - CHAMFERED_POSE.x_mm) <= 2 * res.uncertainty.x_mm
    assert abs(res.z_mm - CHAMFERED_POSE.z_mm) <= 2 * res.uncertainty.z_mm


@pytest.mark.parametrize("cell_gamma", [2.39, 0.6])
def test_a_cell_exponent_the_chamfers_rule_out_refuses_the_door(chamfered_image, cell_gamma):
    """The same door in a cell that says 2.39 (an sRGB camera assumed for a near-linear one) or 0.6: the
    chamfers read with the cell's exponent fit the image markedly worse than read with another, and the door
    is refused, the cell's exponent named."""
    res = locate(chamfered_image, dataclasses.replace(CELL, response_gamma=cell_gamma), CHAMFERED)
    fig = res.diagnostics["response_from_strips"]
    disputed = fig["cell_disputed"]
    assert 0.9 < disputed["best_gamma"] < 1.5
    # the exponents read, each once, the cell's as told (0.6 lies below the plausible 0.8 the ends are kept in)
    assert cell_gamma in fig["gammas"] and len(set(fig["gammas"])) == len(fig["gammas"])
    assert not res.ok and res.error_code == "uncertain"
    assert f"camera.response_gamma {cell_gamma:g}" in res.error and "chamfers' profiles" in res.error
