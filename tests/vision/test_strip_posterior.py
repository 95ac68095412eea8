"""The blur the door's other strips lend an arris strip's fit (strip_posterior.strip_blur_priors), and a
small chamfer whose strip alone cannot tell its border from a wider blur."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from doorloc.cell import DoorSize, load_cell
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.effects import Effects
from doorloc.vision.locate import locate
from doorloc.vision.strip_posterior import (
    BLUR_BETWEEN_EDGES_FRACTION,
    BLUR_BETWEEN_EDGES_PX,
    strip_blur_priors,
)

CELL = load_cell(Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml")

blur = st.floats(0.3, 3.0)
sd = st.floats(0.001, 1.0)


@given(blur, sd, blur, sd, blur, sd, blur)
def test_a_strips_blur_prior_is_the_other_strips_reading_never_its_own(b1, s1, b2, s2, b3, s3, other_b3):
    readings = {"bottom": (b1, s1), "reference": (b2, s2), "far": (b3, s3)}
    priors = strip_blur_priors(readings)
    assert set(priors) == set(readings)
    # the far arris's own reading does not move its prior
    assert strip_blur_priors({**readings, "far": (other_b3, s3)})["far"] == priors["far"]
    for k, (mean, width) in priors.items():
        others = [m for j, (m, _) in readings.items() if j != k]
        assert min(others) - 1e-9 <= mean <= max(others) + 1e-9
        # never narrower than the blur may differ between edges, nor than half the others' disagreement
        assert width >= max(BLUR_BETWEEN_EDGES_PX, BLUR_BETWEEN_EDGES_FRACTION * mean) - 1e-12
        assert width >= 0.5 * abs(others[0] - others[1]) - 1e-12


@given(blur, sd)
def test_a_strip_alone_or_beside_no_reading_gets_no_prior(b, s):
    assert strip_blur_priors({"bottom": (b, s)}) == {}
    priors = strip_blur_priors({"bottom": (b, s), "far": (math.nan, math.inf)})
    assert set(priors) == {"far"}  # the far arris takes the bottom end's; the bottom end has none
    assert math.isclose(priors["far"][0], b, rel_tol=1e-12)


def test_a_small_chamfer_whose_strip_alone_fits_a_wider_blur_as_well_is_answered():
    """A 0.55 mm chamfer under 1.43 px of blur (arris range bench, small set, seed 12111): the bottom end's
    strip fitted alone misfits alike with its border at the strip's outer edge (blur 1.52 px, deficit 0.30)
    and a strip's width further in under a blur of 2.06 px (deficit 1.15), and its posterior spread over
    both: z in doubt by 0.16 mm, refused `uncertain` (0.017 mm off). The reference arris and the far arris
    read 1.40-1.48 px: with their blur as a prior the second reading is ruled out."""
    door = DoorSize(900, 50.0, 2100, arris_mm=0.55204, arris_profile="chamfer")
    pose = DoorPose(7.95786, -6.79171, -0.48206)
    gamma = 1.57254
    eff = Effects(
        albedo_hinge=0.88970,
        albedo_chamfer=0.82498,
        albedo_background=0.14503,
        light_ambient=0.29940,
        light_directional=0.12965,
        light_azimuth_deg=-64.019,
        light_elevation_deg=25.856,
        grain_period_mm=2.3796,
        blur_sigma_px=1.42894,
        read_noise_dn=0.04082,
        gamma=gamma,
    )
    img = render_door(CELL, door, pose, effects=eff, seed=12111).image
    res = locate(img, dataclasses.replace(CELL, response_gamma=gamma), door)
    assert res.ok, res.error
    assert abs(res.z_mm - pose.z_mm) <= 2.0 * res.uncertainty.z_mm
    assert abs(res.x_mm - pose.x_mm) <= 2.0 * res.uncertainty.x_mm
    assert res.diagnostics["arris_fit"]["bottom"]["deficit_sigma"] < 0.15
