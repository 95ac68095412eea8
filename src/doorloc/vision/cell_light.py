"""The cell's light measured from images of its doors: the direction ``locate.light_direction_deg`` states.

A rounded arris's strip is shaded by the light; under the cell's true light its shading fits as well as a
free shading does (the misfit ratio ``diagnostics.arris_fit.<line>.stated_light.misfit_over_free`` about
1), under a light far from it several times worse. One door's three strips hardly tell the light (they fit
many directions about alike), but the lamps of a cell are fixed: over several doors with rounded arrises
the mean log ratio has its least near the true direction. :func:`measure_cell_light` takes it over a grid
of directions, then over a grid four times finer around the best.

Why by locating each door under each trial light, not by a fit of its own: the ratio is what locate itself
will use to decide whether the stated light explains a strip (``arris_strip.STATED_LIGHT_MISFIT_RATIO``),
measured on the strips locate finds, in its frames; a second model of the strips would be a second thing
to keep right. It costs a locate per door and trial light (about half a second a door with roundings):
minutes, once for a cell.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.pose import direction_cell
from doorloc.vision.locate import locate

__all__ = [
    "COARSE_AZIMUTHS",
    "COARSE_ELEVATIONS",
    "LightMeasurement",
    "LightNotMeasurable",
    "measure_cell_light",
]

#: the first grid, deg: azimuths from one side of the hinge face to the other, elevations from below the
#: door's bottom end to high above it (a light behind the hinge face, |azimuth| > 90, would leave the
#: face itself dark)
COARSE_AZIMUTHS = tuple(range(-80, 81, 20))
COARSE_ELEVATIONS = (-20, 0, 20, 40, 60)
#: a second least of the mean log ratio this close to the least, and this far from it (deg), is named as
#: another light the doors cannot rule out: the mirror of the true light across the camera's axis scored
#: within 0.02 of it on eight doors lit from azimuth -55 deg
RUNNER_UP_MARGIN, RUNNER_UP_APART_DEG = 0.05, 40.0
#: the stated doubt of a measured light, deg, at least: the turns of ``locate.light_direction_sigma_deg``
#: at 10 deg cost no answer where the light is right, and a light 10 deg off stays within 2 sigma
MEASURED_SIGMA_FLOOR_DEG = 10.0


class LightNotMeasurable(ValueError):
    """The images cannot tell the light: no door with a rounded arris, or no strip locate could fit."""


@dataclass(frozen=True)
class LightMeasurement:
    """The cell's light as measured by :func:`measure_cell_light`.

    ``direction_deg``: ``[azimuth, elevation]``, deg, cell frame (as ``locate.light_direction_deg``);
    ``sigma_deg``: its doubt to state (``locate.light_direction_sigma_deg``): the widest angle from it of
    the fine grid's directions that score within ``RUNNER_UP_MARGIN`` of it, at least
    ``MEASURED_SIGMA_FLOOR_DEG``; ``score``: the mean log misfit ratio there over ``strips`` rounded
    strips of ``doors`` doors (0: as well as a free shading); ``runner_up_deg`` / ``runner_up_score``:
    another direction at least ``RUNNER_UP_APART_DEG`` away that scores within ``RUNNER_UP_MARGIN`` of
    it, or None (check which side the lamp is on)."""

    direction_deg: tuple[float, float]
    sigma_deg: float
    score: float
    strips: int
    doors: int
    runner_up_deg: tuple[float, float] | None = None
    runner_up_score: float | None = None


def _angle_deg(a: tuple[float, float], b: tuple[float, float]) -> float:
    c = float(direction_cell(*a) @ direction_cell(*b))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def _scores(
    frames: Sequence[tuple[np.ndarray, DoorSize]],
    cell: Cell,
    lights: Sequence[tuple[float, float]],
    progress: Callable[[str], None] | None = None,
) -> tuple[dict[tuple[float, float], float], int, int]:
    """Each light's mean log misfit ratio over the rounded strips of ``frames``; the strips and the doors
    that voted (under the first light). ``progress`` hears of each light done."""
    out: dict[tuple[float, float], float] = {}
    strips = doors = 0
    for k, light in enumerate(lights):
        # (the light's doubt is not wanted here: its turns would only cost time)
        cfg = replace(cell.locate, light_direction_deg=light, light_direction_sigma_deg=0.0)
        logs: list[float] = []
        for image, door in frames:
            res = locate(image, cell, door, config=cfg)
            ratios = [
                f["stated_light"]["misfit_over_free"]
                for f in res.diagnostics.get("arris_fit", {}).values()
                if "stated_light" in f
            ]
            logs += [math.log(max(r, 1e-3)) for r in ratios]
            doors += int(k == 0 and bool(ratios))
        if k == 0:
            strips = len(logs)
        out[light] = float(np.mean(logs)) if logs else math.nan
        if progress is not None:
            progress(
                f"light [{light[0]:+.0f}, {light[1]:+.0f}] deg: {out[light]:.3f} ({k + 1} of {len(lights)})"
            )
    return out, strips, doors


def measure_cell_light(
    frames: Sequence[tuple[np.ndarray, DoorSize]],
    cell: Cell,
    *,
    azimuths: Sequence[float] = COARSE_AZIMUTHS,
    elevations: Sequence[float] = COARSE_ELEVATIONS,
    fine_steps: int = 2,
    progress: Callable[[str], None] | None = None,
) -> LightMeasurement:
    """The direction of the cell's light from images of its doors, ``frames`` (image, door) pairs, the doors
    with rounded arrises (``arris_profile: round``; chamfers and sharp edges do not tell the light).

    The mean log misfit ratio over the doors' rounded strips at every ``azimuths`` x ``elevations``
    direction (deg, cell frame), then on a grid a quarter of its steps wide around the least, ``fine_steps``
    of them each way. ``progress`` hears a line for each direction scored (a locate of every door).

    Raises
    ------
    LightNotMeasurable
        No frame has a rounded arris whose strip locate could fit (the images, or their doors, cannot
        tell the light).
    """
    if not any(door.arris_mm > 0 and door.arris_profile == "round" for _, door in frames):
        raise LightNotMeasurable(
            "no door with a rounded arris among the images (arris_profile round, arris_mm > 0 in the cell's "
            "default door or the manifest): only a rounding's shading tells the light"
        )
    coarse = [(float(a), float(e)) for e in elevations for a in azimuths]
    scores, strips, doors = _scores(frames, cell, coarse, progress)
    if strips == 0 or all(math.isnan(v) for v in scores.values()):
        raise LightNotMeasurable(
            "locate fitted no rounded arris strip on these images: they cannot tell the light "
            "(check that the doors are in the fixture and their recipes' arris_mm)"
        )

    def at(k: tuple[float, float]) -> float:
        return scores[k] if not math.isnan(scores[k]) else math.inf  # (a light no strip was fitted under)

    best = min(scores, key=at)
    da = (azimuths[1] - azimuths[0]) / 4 if len(azimuths) > 1 else 5.0
    de = (elevations[1] - elevations[0]) / 4 if len(elevations) > 1 else 5.0
    steps = range(-fine_steps, fine_steps + 1)
    fine = [
        (best[0] + i * da, min(max(best[1] + j * de, -89.0), 89.0))
        for j in steps
        for i in steps
        if (i, j) != (0, 0)
    ]
    fine_scores, _, _ = _scores(frames, cell, fine, progress)
    scores.update(fine_scores)
    best = min(scores, key=at)
    near = [k for k in [*fine, best] if at(k) <= scores[best] + RUNNER_UP_MARGIN]
    sigma = max(MEASURED_SIGMA_FLOOR_DEG, max(_angle_deg(best, k) for k in near))
    others = [
        k
        for k in coarse
        if _angle_deg(best, k) >= RUNNER_UP_APART_DEG and at(k) <= scores[best] + RUNNER_UP_MARGIN
    ]
    runner = min(others, key=at) if others else None
    return LightMeasurement(
        direction_deg=best,
        sigma_deg=round(sigma, 1),
        score=scores[best],
        strips=strips,
        doors=doors,
        runner_up_deg=runner,
        runner_up_score=scores[runner] if runner is not None else None,
    )
