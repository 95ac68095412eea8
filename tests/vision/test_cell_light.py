"""The cell's light measured from its doors (``doorloc.vision.cell_light``) and ``doorloc measure-light``."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.pose import DoorPose, direction_cell, directions_apart_deg
from doorloc.vision import cell_light, light_search
from doorloc.vision.cell_light import LightMeasurement, LightNotMeasurable, measure_cell_light

_spec = importlib.util.spec_from_file_location("lit_doors", Path(__file__).with_name("lit_doors.py"))
assert _spec is not None and _spec.loader is not None
lit_doors = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("lit_doors", lit_doors)
_spec.loader.exec_module(lit_doors)
lit_door, CELL, CELL_PATH, LIGHT = lit_doors.lit_door, lit_doors.CELL, lit_doors.CELL_PATH, lit_doors.LIGHT


def test_the_light_of_a_cell_is_found_near_its_direction():
    """Two doors with roundings of 2.4 and 1.6 mm under the cell's lamp at azimuth -45, elevation 15 deg: on
    a coarse grid 40 deg apart that holds the lamp's mirror across the camera's axis (40, 20) as well as a
    direction near it (-40, 20), its quarter steps around the best and a grid a quarter as fine again about
    theirs, the measured light lies within 2 deg of the lamp, its doubt at least the floor, and both doors'
    strips voted; each direction tried is reported as it is scored."""
    frames = [
        lit_door(2.4, "round", DoorPose(2.0, -3.0, 0.6), 1.1, 1),
        lit_door(1.6, "round", DoorPose(-4.0, 2.0, -1.0), 1.3, 2),
    ]
    cell = dataclasses.replace(CELL, response_gamma=1.8)
    heard: list[str] = []
    m = measure_cell_light(
        frames,
        cell,
        azimuths=(-80.0, -40.0, 0.0, 40.0, 80.0),
        elevations=(20.0,),
        fine_steps=1,
        progress=heard.append,
    )
    # every door and direction is told: the doors, the grid, its quarter steps, and the searches of
    # light_search.finer_light (3 x 3 directions and their quarter steps: once about the best, twice about
    # each rival)
    assert len(heard) == 2 + 5 + 8 + 33 * (1 + 2 * len(m.rivals)) and heard[-1].endswith("(24 of 24)")
    assert heard[0].startswith("door 1 of 2 located")
    off = math.degrees(math.acos(min(1.0, float(direction_cell(*m.direction_deg) @ direction_cell(*LIGHT)))))
    assert off <= 2.0, (m, off)  # (the quarter steps alone are 10 deg apart here; found to 0.0 deg)
    assert m.sigma_deg >= light_search.MEASURED_SIGMA_FLOOR_DEG
    assert m.doors == 2 and m.strips >= 4


def test_doors_under_a_diffuse_light_tell_no_direction():
    """The same two roundings under ambient light alone: their strips fit every direction about alike, so no
    direction is stated (it would have been printed with a doubt of 10 deg, and a light stated wrong lets
    a strip's shading choose the wrong border)."""
    frames = [
        lit_door(2.4, "round", DoorPose(2.0, -3.0, 0.6), 1.1, 1, lamp=False),
        lit_door(1.6, "round", DoorPose(-4.0, 2.0, -1.0), 1.3, 2, lamp=False),
    ]
    with pytest.raises(LightNotMeasurable, match="diffuse"):
        measure_cell_light(frames, dataclasses.replace(CELL, response_gamma=1.8))


def test_doors_without_a_rounding_cannot_tell_the_light():
    frames = [
        lit_door(2.0, "chamfer", DoorPose(0.0, 0.0, 0.0), 1.0, 3),
        lit_door(0.0, "chamfer", DoorPose(), 1.0, 4),
    ]
    with pytest.raises(LightNotMeasurable, match="rounded arris"):
        measure_cell_light(frames, CELL)


def _folder_with_onelit_door(tmp_path: Path) -> Path:
    d = tmp_path / "doors"
    d.mkdir()
    cv2.imwrite(str(d / "door_1.png"), lit_door(2.0, "round", DoorPose(1.0, 1.0, 0.5), 1.0, 5)[0])
    return d


def test_measure_light_prints_the_lines_for_the_cell_and_warns_of_another_side(tmp_path, monkeypatch):
    seen = {}

    def measured(frames, cell, progress=None):
        seen["doors"] = [door for _, door in frames]
        return LightMeasurement(
            (-44.0, 16.0), 10.0, 0.021, 6, 2, runner_up_deg=(40.0, 20.0), runner_up_score=0.05
        )

    monkeypatch.setattr(cell_light, "measure_cell_light", measured)
    folder = _folder_with_onelit_door(tmp_path)
    (tmp_path / "doors.csv").write_text("image,width_mm,thickness_mm,arris_mm\ndoor_1.png,900,50,2.0\n")
    doc = yaml.safe_load(CELL_PATH.read_text())
    doc["door"]["arris_profile"] = "round"
    doc["camera"]["dist_coeffs"] = [0.0] * 5
    cell_path = tmp_path / "cell.yaml"
    cell_path.write_text(yaml.safe_dump(doc))
    res = CliRunner().invoke(
        app,
        ["measure-light", str(folder), "--cell", str(cell_path), "--manifest", str(tmp_path / "doors.csv")],
    )
    assert res.exit_code == 0, res.output
    assert seen["doors"][0].arris_mm == 2.0 and seen["doors"][0].arris_profile == "round"
    assert (
        "light_direction_deg: [-44.0, 16.0]" in res.stdout and "light_direction_sigma_deg: 10" in res.stdout
    )
    assert "azimuth +40" in res.stderr and "which side" in res.stderr


def test_measure_light_exits_1_where_the_doors_have_no_rounding_and_2_on_bad_input(tmp_path):
    folder = _folder_with_onelit_door(tmp_path)
    res = CliRunner().invoke(app, ["measure-light", str(folder), "--cell", str(CELL_PATH)])
    assert res.exit_code == 1, res.output
    assert "rounded arris" in res.stderr and "Traceback" not in res.output
    res = CliRunner().invoke(app, ["measure-light", str(tmp_path / "nowhere"), "--cell", str(CELL_PATH)])
    assert res.exit_code == 2, res.output
    assert "nowhere" in res.stderr and "Traceback" not in res.output


def _two_valleys(lamp: tuple[float, float], mirror: tuple[float, float]):
    """A strip's misfit ratio under trial lights: a narrow deep valley at ``lamp`` (0.5 in log per 5 deg
    squared, least 0.01) and a wide shallow one at ``mirror`` (0.3 per 20 deg squared, least 0.03)."""
    at_lamp, at_mirror = direction_cell(*lamp), direction_cell(*mirror)

    def score(directions: np.ndarray) -> np.ndarray:
        off_l = np.degrees(np.arccos(np.clip(directions @ at_lamp, -1.0, 1.0)))
        off_m = np.degrees(np.arccos(np.clip(directions @ at_mirror, -1.0, 1.0)))
        return np.exp(np.minimum(0.01 + 0.5 * (off_l / 5.0) ** 2, 0.03 + 0.3 * (off_m / 20.0) ** 2))

    return score


def test_the_finer_search_finds_a_narrow_valley_the_first_grid_stepped_over():
    """A lamp whose valley is narrower than the first grid's 20 deg steps scores worse on that grid than its
    wide mirror, which the first search states; sought again about the first grid's other local least
    (a rival), it is found to a degree and a half and stated, the mirror named as the runner-up."""
    lamp, mirror = (52.7, 31.0), (-57.5, 28.75)
    strips = [[_two_valleys(lamp, mirror)]]
    first = light_search.light_from_strips(strips)
    assert directions_apart_deg(first.direction_deg, lamp) > 40.0 and first.rivals
    m = light_search.finer_light(strips, first)
    assert directions_apart_deg(m.direction_deg, lamp) <= 1.5, m
    assert m.score < 0.02 and m.runner_up_deg is not None
    assert directions_apart_deg(m.runner_up_deg, mirror) <= 5.0, m
    assert m.sigma_deg >= light_search.MEASURED_SIGMA_FLOOR_DEG


def test_the_finer_search_keeps_the_doubt_of_a_wide_valley():
    """Strips that fit every direction within 20 deg of the lamp about alike (one wide valley): the first
    search states a doubt wider than the floor, and the finer search, whose own grid reaches only a few
    degrees, keeps it."""
    lamp = (30.0, 20.0)
    at = direction_cell(*lamp)

    def wide(directions: np.ndarray) -> np.ndarray:
        off = np.degrees(np.arccos(np.clip(directions @ at, -1.0, 1.0)))
        return np.exp(0.01 + 0.05 * (off / 20.0) ** 2)

    first = light_search.light_from_strips([[wide]])
    assert first.sigma_deg > light_search.MEASURED_SIGMA_FLOOR_DEG
    m = light_search.finer_light([[wide]], first)
    assert directions_apart_deg(m.direction_deg, lamp) <= 1.5 and m.sigma_deg >= first.sigma_deg, m


def _one_lamp(lamp: tuple[float, float], depth: float = 0.6):
    """A rounded strip's score (misfit over its free shading's) that is least, 1, under ``lamp`` and rises
    with the angle from it (``depth`` in log at 60 deg)."""
    at = direction_cell(*lamp)

    def score(directions: np.ndarray) -> np.ndarray:
        off = np.degrees(np.arccos(np.clip(directions @ at, -1.0, 1.0)))
        return np.exp(depth * (off / 60.0) ** 2)

    return score


def test_doors_that_rule_out_the_light_best_for_all_are_named():
    """Three doors under one lamp and one under another: the light best for all is the lamp's, each of the
    three fits it as well as its own, and only the fourth door's strips rule it out (its misfit there over
    1.25 times its own light's); at the fourth door's lamp the three others do."""
    lamp, other = (-45.0, 15.0), (50.0, 30.0)
    strips = [[_one_lamp(lamp)] * 2, [_one_lamp(lamp)], [], [_one_lamp(other)] * 3, [_one_lamp(lamp)]]
    assert cell_light.doors_ruling_out(strips, lamp) == [3]
    assert cell_light.doors_ruling_out(strips, other) == [0, 1, 4]


def test_doors_each_under_a_lamp_of_its_own_tell_no_cell_light():
    """Five roundings of 1.2-2.4 mm, each lit by a lamp of its own (from either side, 10-45 deg up): some
    light is best for all of them on average, but several doors' strips fit their own lamp far better, so
    no light is stated for the cell (one light stated for every door would be wrong for most of them)."""
    lamps = [(-60.0, 20.0), (55.0, 30.0), (-25.0, 45.0), (70.0, 10.0), (35.0, 25.0)]
    poses = [DoorPose(2.0, -3.0, 0.6), DoorPose(-4.0, 2.0, -1.0), DoorPose(5.0, 4.0, 1.2)]
    frames = [
        lit_door(a, "round", poses[k % 3], blur, 10 + k, light=lamp)
        for k, (a, blur, lamp) in enumerate(
            zip((2.4, 1.6, 1.2, 2.0, 1.8), (1.1, 1.3, 0.9, 1.0, 1.2), lamps, strict=True)
        )
    ]
    with pytest.raises(LightNotMeasurable, match="lit from different sides"):
        measure_cell_light(frames, dataclasses.replace(CELL, response_gamma=lit_doors.CAMERA_GAMMA))
