"""The cell's light measured from images of its doors: the direction ``locate.light_direction_deg`` states.

A rounded arris's strip is shaded by the light; under the cell's true light its shading fits as well as a
free shading does (the misfit ratio ``diagnostics.arris_fit.<line>.stated_light.misfit_over_free`` about
1), under a light far from it several times worse. One door's three strips hardly tell the light (they fit
many directions about alike), but the lamps of a cell are fixed: over several doors with rounded arrises
the mean log ratio has its least near the true direction. :func:`measure_cell_light` takes it over a grid
of directions, then over a grid four times finer around the best.

Why from locate's own strip fits, not a fit of its own: the ratio is what locate itself will use to decide
whether the stated light explains a strip (``stated_light.STATED_LIGHT_MISFIT_RATIO``), measured on the
strips locate finds, in its frames; a second model of the strips would be a second thing to keep right.
Each door is located once, without a light (``LocateTrace.arris_fits``), and its rounded strips are scored
under every trial light (``StripFit.misfit_under_light``): the strips are the ones a locate under that light
would fit, read at the pose found without it (the stated light moves a rounded door's pose by hundredths of
a millimetre, a strip's profiles by as little). Locating each door again under each trial light gave the
same directions on the six rendered cells of ``bench/bench_cell_light.py`` (scores within 0.007), at
about fifteen times the cost.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.pose import direction_cell, directions_apart_deg
from doorloc.vision.locate import LocateTrace, locate

__all__ = [
    "COARSE_AZIMUTHS",
    "COARSE_ELEVATIONS",
    "DIFFUSE_SHARE",
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
#: a share of the first grid's directions scoring within ``RUNNER_UP_MARGIN`` of the best beyond which the
#: doors cannot tell a direction: on the six rendered cells of ``bench/bench_cell_light.py`` 1-2 of the 45
#: did under the cell's lamp, all 45 under ambient light alone (``--ambient``: scores within 0.001-0.008 of
#: each other), where a direction would still have been printed with a doubt of 10 deg
DIFFUSE_SHARE = 0.5
#: the stated doubt of a measured light, deg, at least: the turns of ``locate.light_direction_sigma_deg``
#: at 10 deg cost no answer where the light is right, and a light 10 deg off stays within 2 sigma
MEASURED_SIGMA_FLOOR_DEG = 10.0


class LightNotMeasurable(ValueError):
    """The images cannot tell the light: no door with a rounded arris, no strip locate could fit, or strips
    that fit most directions alike (a diffuse light)."""


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


#: a rounded strip's misfit under a light from a direction (unit vector, cell frame) over its free shading's
StripScore = Callable[[np.ndarray], float]


def _scores(
    strips: Sequence[Sequence[StripScore]],
    lights: Sequence[tuple[float, float]],
    progress: Callable[[str], None] | None = None,
) -> dict[tuple[float, float], float]:
    """Each light's mean log misfit ratio over the rounded strips of the doors, ``strips`` (per door, at
    least one strip in all); ``progress`` hears of each light done."""
    out: dict[tuple[float, float], float] = {}
    for k, light in enumerate(lights):
        direction = direction_cell(*light)
        logs = [math.log(max(score(direction), 1e-3)) for door in strips for score in door]
        out[light] = float(np.mean(logs))
        if progress is not None:
            progress(
                f"light [{light[0]:+.0f}, {light[1]:+.0f}] deg: {out[light]:.3f} ({k + 1} of {len(lights)})"
            )
    return out


def _rounded_strips(
    frames: Sequence[tuple[np.ndarray, DoorSize]],
    cell: Cell,
    progress: Callable[[str], None] | None = None,
) -> list[list[StripScore]]:
    """Per frame, its rounded strips as locate fitted them (``StripFit.misfit_under_light``), each door
    located once without a light; ``progress`` hears of each door done."""
    cfg = replace(cell.locate, light_direction_deg=None)
    out = []
    for k, (image, door) in enumerate(frames):
        trace = LocateTrace()
        locate(image, cell, door, config=cfg, trace=trace)
        out.append(
            [f.misfit_under_light for f in trace.arris_fits.values() if f.misfit_under_light is not None]
        )
        if progress is not None:
            progress(f"door {k + 1} of {len(frames)} located: {len(out[-1])} rounded strips")
    return out


def measure_cell_light(
    frames: Sequence[tuple[np.ndarray, DoorSize]],
    cell: Cell,
    *,
    azimuths: Sequence[float] = COARSE_AZIMUTHS,
    elevations: Sequence[float] = COARSE_ELEVATIONS,
    fine_steps: int = 2,
    diffuse_share: float = DIFFUSE_SHARE,
    progress: Callable[[str], None] | None = None,
) -> LightMeasurement:
    """The direction of the cell's light from images of its doors, ``frames`` (image, door) pairs, the doors
    with rounded arrises (``arris_profile: round``; chamfers and sharp edges do not tell the light).

    The mean log misfit ratio over the doors' rounded strips at every ``azimuths`` x ``elevations``
    direction (deg, cell frame), then on a grid a quarter of its steps wide around the least, ``fine_steps``
    of them each way. ``diffuse_share``: the share of the first grid's directions scoring alike
    (``RUNNER_UP_MARGIN``) beyond which no direction is stated (1 or more: the best is always stated).
    ``progress`` hears a line for each door located and each direction scored.

    Raises
    ------
    LightNotMeasurable
        No frame has a rounded arris whose strip locate could fit, or the strips fit every direction
        about alike (a diffuse light, or roundings too small to tell it): the images cannot tell the light.
    """
    if not any(door.arris_mm > 0 and door.arris_profile == "round" for _, door in frames):
        raise LightNotMeasurable(
            "no door with a rounded arris among the images (arris_profile round, arris_mm > 0 in the cell's "
            "default door or the manifest): only a rounding's shading tells the light"
        )
    coarse = [(float(a), float(e)) for e in elevations for a in azimuths]
    per_door = _rounded_strips(frames, cell, progress)
    strips, doors = sum(len(d) for d in per_door), sum(1 for d in per_door if d)
    if strips == 0:
        raise LightNotMeasurable(
            "locate fitted no rounded arris strip on these images: they cannot tell the light "
            "(check that the doors are in the fixture and their recipes' arris_mm)"
        )
    scores = _scores(per_door, coarse, progress)
    least = min(scores.values())
    alike = sum(v <= least + RUNNER_UP_MARGIN for v in scores.values())
    if alike > diffuse_share * len(coarse):
        raise LightNotMeasurable(
            f"the doors' roundings are shaded about alike under {alike} of the {len(coarse)} directions "
            "tried: the light is diffuse (or the roundings too small to tell it), and no direction can be "
            "stated; leave locate.light_direction_deg unset"
        )

    best = min(scores, key=scores.__getitem__)
    da = (azimuths[1] - azimuths[0]) / 4 if len(azimuths) > 1 else 5.0
    de = (elevations[1] - elevations[0]) / 4 if len(elevations) > 1 else 5.0
    steps = range(-fine_steps, fine_steps + 1)
    fine = [
        (best[0] + i * da, min(max(best[1] + j * de, -89.0), 89.0))
        for j in steps
        for i in steps
        if (i, j) != (0, 0)
    ]
    scores.update(_scores(per_door, fine, progress))
    best = min(scores, key=scores.__getitem__)
    near = [k for k in [*fine, best] if scores[k] <= scores[best] + RUNNER_UP_MARGIN]
    sigma = max(MEASURED_SIGMA_FLOOR_DEG, max(directions_apart_deg(best, k) for k in near))
    others = [
        k
        for k in coarse
        if directions_apart_deg(best, k) >= RUNNER_UP_APART_DEG
        and scores[k] <= scores[best] + RUNNER_UP_MARGIN
    ]
    runner = min(others, key=scores.__getitem__) if others else None
    return LightMeasurement(
        direction_deg=best,
        sigma_deg=round(sigma, 1),
        score=scores[best],
        strips=strips,
        doors=doors,
        runner_up_deg=runner,
        runner_up_score=scores[runner] if runner is not None else None,
    )
