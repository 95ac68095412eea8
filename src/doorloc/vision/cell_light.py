"""The cell's light measured from images of its doors: the direction ``locate.light_direction_deg`` states.

One door's three rounded strips hardly tell the light (they fit many directions about alike), but the
lamps of a cell are fixed: over several doors with rounded arrises the mean log misfit ratio of
:func:`doorloc.vision.light_search.light_from_strips` has its least near the true direction.

Why from locate's own strip fits, not a fit of its own: the ratio is what locate itself will use to decide
whether the stated light explains a strip (``stated_light.STATED_LIGHT_MISFIT_RATIO``), measured on the
strips locate finds, in its frames; a second model of the strips would be a second thing to keep right.
Each door is located once, without a light (``LocateTrace.arris_fits``), and its rounded strips are scored
under every trial light (``StripFit.misfit_under_lights``): the strips are the ones a locate under that light
would fit, read at the pose found without it (the stated light moves a rounded door's pose by hundredths of
a millimetre, a strip's profiles by as little). Locating each door again under each trial light gave the
same directions on the six rendered cells of ``bench/bench_cell_light.py`` (scores within 0.007), at
about fifteen times the cost.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.vision import light_search as ls
from doorloc.vision.light_search import LightMeasurement, LightNotMeasurable, StripScore
from doorloc.vision.locate import LocateTrace, locate
from doorloc.vision.strip_response import ARC_FINE_STEPS, ARC_RULED_OUT

# (the measurement and its refusal are named here too: they are what a caller of measure_cell_light meets)
__all__ = [
    "DISAGREEING_DOORS",
    "LightMeasurement",
    "LightNotMeasurable",
    "doors_ruling_out",
    "measure_cell_light",
    "own_lights",
    "rounded_strips",
]

#: doors whose strips rule the light best for all out (:func:`doors_ruling_out`) from which the doors share
#: no lamp. One door may do so alone where the model misses its finish or the light search misses its own
#: lamp (on six rendered cells under a finish of power 0.5 and six of power 2, one lamp each, one door of
#: one cell of each went 1.24 and 1.26 times past the light best for all, every other door of the twelve
#: cells within 1.1); on six cells whose eight doors had each a lamp of its own, 3 to 5 doors of every
#: cell did (bench/bench_cell_light.py --mixed-lights)
DISAGREEING_DOORS = 2


def rounded_strips(
    frames: Sequence[tuple[np.ndarray, DoorSize]],
    cell: Cell,
    progress: Callable[[str], None] | None = None,
) -> list[list[StripScore]]:
    """Per frame, its rounded strips as locate fitted them (``StripFit.misfit_under_lights``), each door
    located once without a light of its own (nor the shoulder's doubt, which locates a door again for its
    sigma alone); ``progress`` hears of each door done."""
    cfg = replace(cell.locate, light_direction_deg=None, light_from_door=False, response_shoulder_knee=1.0)
    out = []
    for k, (image, door) in enumerate(frames):
        trace = LocateTrace()
        locate(image, cell, door, config=cfg, trace=trace)
        out.append(
            [f.misfit_under_lights for f in trace.arris_fits.values() if f.misfit_under_lights is not None]
        )
        if progress is not None:
            progress(f"door {k + 1} of {len(frames)} located: {len(out[-1])} rounded strips")
    return out


def measure_cell_light(
    frames: Sequence[tuple[np.ndarray, DoorSize]],
    cell: Cell,
    *,
    azimuths: Sequence[float] = ls.COARSE_AZIMUTHS,
    elevations: Sequence[float] = ls.COARSE_ELEVATIONS,
    fine_steps: int = 2,
    diffuse_share: float = ls.DIFFUSE_SHARE,
    progress: Callable[[str], None] | None = None,
) -> LightMeasurement:
    """The direction of the cell's light from images of its doors, ``frames`` (image, door) pairs, the doors
    with rounded arrises (``arris_profile: round``; chamfers and sharp edges do not tell the light).

    Each door located once, then :func:`doorloc.vision.light_search.light_from_strips` over all their
    rounded strips (``azimuths``, ``elevations``, ``fine_steps``, ``diffuse_share`` as there).
    ``progress`` hears a line for each door located and each direction scored.

    Raises
    ------
    LightNotMeasurable
        No frame has a rounded arris whose strip locate could fit, or the strips fit every direction
        about alike (a diffuse light, or roundings too small to tell it): the images cannot tell the light.
        Or ``DISAGREEING_DOORS`` doors or more rule the light best for all out (:func:`doors_ruling_out`):
        no lamp is common to the doors.
    """
    if not any(door.arris_mm > 0 and door.arris_profile == "round" for _, door in frames):
        raise LightNotMeasurable(
            "no door with a rounded arris among the images (arris_profile round, arris_mm > 0 in the cell's "
            "default door or the manifest): only a rounding's shading tells the light"
        )
    strips = rounded_strips(frames, cell, progress)
    first = ls.light_from_strips(
        strips,
        azimuths=azimuths,
        elevations=elevations,
        fine_steps=fine_steps,
        diffuse_share=diffuse_share,
        progress=progress,
    )
    light = ls.finer_light(strips, first, progress)
    ruling_out = doors_ruling_out(strips, light.direction_deg)
    if len(ruling_out) >= DISAGREEING_DOORS:
        az, el = light.direction_deg
        raise LightNotMeasurable(
            f"the doors are lit from different sides: {len(ruling_out)} of the {light.doors} doors' roundings fit "
            f"a light of their own at least {ARC_RULED_OUT:g} times better than the one best for all (azimuth "
            f"{az:.0f}, elevation {el:.0f} deg), so no lamp is common to them (each lit from its own side, "
            "daylight, lamps moved between the images); leave locate.light_direction_deg unset: locate then "
            "reads each door's own light"
        )
    return light


def own_lights(strips: Sequence[Sequence[StripScore]]) -> list[LightMeasurement | None]:
    """Per door, its rounded strips' (``strips``, per door) best light and their mean log misfit ratio under
    it (:func:`doorloc.vision.light_search.light_of_one_door`, a quarter step finer one step around the
    best, as an exponent's strips are scored: ``strip_response.ARC_FINE_STEPS``); None for a door without a
    strip."""
    return [ls.light_of_one_door(door, fine_steps=ARC_FINE_STEPS) for door in strips]


def doors_ruling_out(strips: Sequence[Sequence[StripScore]], light: tuple[float, float]) -> list[int]:
    """The doors (their places in ``strips``, per door its rounded strips' scores) whose strips rule
    ``light`` ([azimuth, elevation] deg) out as locate rules an exponent out: their misfit under it
    ``strip_response.ARC_RULED_OUT`` times or more their misfit under their own best light
    (:func:`own_lights`). Under one lamp the light best for all is each door's own, within the light
    search's steps (eight doors each of six rendered cells: within 1.05); of eight doors each lit from its
    own side, the farthest of each cell's went 2.2-16 times past it."""
    ruled_out = math.log(ARC_RULED_OUT)
    under = ls.scores_under(strips, light)
    return [
        k
        for k, (own, at) in enumerate(zip(own_lights(strips), under, strict=True))
        if own is not None and at is not None and at - own.score > ruled_out
    ]
