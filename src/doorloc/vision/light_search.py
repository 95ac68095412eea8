"""The direction of the light from rounded arrises' strips: the least of their misfit under trial lights.

A rounded arris's strip is shaded by the light; under the true light its shading fits as well as a free
shading does (the misfit ratio ``diagnostics.arris_fit.<line>.stated_light.misfit_over_free`` about 1),
under a light far from it several times worse. :func:`light_from_strips` takes the mean log ratio over
the strips (``StripFit.misfit_under_lights``, each strip as locate fitted it) over a grid of directions,
then over a grid four times finer around the best. Over several doors of a cell (fixed lamps) it is
:func:`doorloc.vision.cell_light.measure_cell_light`; over one door's strips it is the light that door's
locate states where the cell states none (``locate.light_from_door``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from doorloc.pose import direction_cell, directions_apart_deg

__all__ = [
    "COARSE_AZIMUTHS",
    "COARSE_ELEVATIONS",
    "DIFFUSE_SHARE",
    "FINER_GRID_DEG",
    "RIVALS_SOUGHT",
    "RIVAL_GRID_DEG",
    "MEASURED_SIGMA_FLOOR_DEG",
    "LightMeasurement",
    "LightNotMeasurable",
    "StripScore",
    "finer_light",
    "light_from_strips",
    "light_of_one_door",
    "scores_under",
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
#: the step of the grid a measured light is sought on again about the first search's best, deg
#: (:func:`finer_light`)
FINER_GRID_DEG = 5.0
#: how many of the first grid's other local least directions :func:`finer_light` seeks again, and the step
#: of the grid it first seeks each on (the first grid's own), deg
RIVALS_SOUGHT = 2
RIVAL_GRID_DEG = 20.0
#: the stated doubt of a measured light, deg, at least: the turns of ``locate.light_direction_sigma_deg``
#: at 10 deg cost no answer where the light is right, and a light 10 deg off stays within 2 sigma
MEASURED_SIGMA_FLOOR_DEG = 10.0


class LightNotMeasurable(ValueError):
    """The images cannot tell the light: no door with a rounded arris, no strip locate could fit, or strips
    that fit most directions alike (a diffuse light)."""


@dataclass(frozen=True)
class LightMeasurement:
    """A light measured by :func:`light_from_strips`.

    ``direction_deg``: ``[azimuth, elevation]``, deg, cell frame (as ``locate.light_direction_deg``);
    ``sigma_deg``: its doubt to state (``locate.light_direction_sigma_deg``): the widest angle from it of
    the fine grid's directions that score within ``RUNNER_UP_MARGIN`` of it, at least
    ``MEASURED_SIGMA_FLOOR_DEG``; ``score``: the mean log misfit ratio there over ``strips`` rounded
    strips of ``doors`` doors (0: as well as a free shading); ``runner_up_deg`` / ``runner_up_score``:
    another direction at least ``RUNNER_UP_APART_DEG`` away that scores within ``RUNNER_UP_MARGIN`` of
    it, or None (check which side the lamp is on); ``alike_share``: the share of the first grid's
    directions scoring within ``RUNNER_UP_MARGIN`` of the best (near 1: a diffuse light); ``rivals``: the
    first grid's best ``RIVALS_SOUGHT`` directions that no neighbour on it beats, ``RUNNER_UP_APART_DEG``
    or more from the best, which :func:`finer_light` seeks again (a valley narrower than the grid's steps
    may score worse on it than a wider one)."""

    direction_deg: tuple[float, float]
    sigma_deg: float
    score: float
    strips: int
    doors: int
    runner_up_deg: tuple[float, float] | None = None
    runner_up_score: float | None = None
    alike_share: float = 0.0
    rivals: tuple[tuple[float, float], ...] = ()

    @property
    def tells_one_direction(self) -> bool:
        """Whether the strips single this light out: no other direction ``RUNNER_UP_APART_DEG`` away fits
        about as well (the runner-up :func:`light_from_strips` reports for a cell's light), and no more than
        ``DIFFUSE_SHARE`` of the first grid does (beyond which it states no cell light at all)."""
        return self.runner_up_deg is None and self.alike_share <= DIFFUSE_SHARE


#: a rounded strip's misfits under lights from directions (``(n, 3)`` unit vectors, cell frame) over its
#: free shading's, ``(n,)`` (``StripFit.misfit_under_lights``)
StripScore = Callable[[np.ndarray], np.ndarray]


def _scores(
    strips: Sequence[Sequence[StripScore]],
    lights: Sequence[tuple[float, float]],
    progress: Callable[[str], None] | None = None,
) -> dict[tuple[float, float], float]:
    """Each light's mean log misfit ratio over the rounded strips of the doors, ``strips`` (per door, at
    least one strip in all); ``progress`` hears each light's score."""
    directions = np.array([direction_cell(*light) for light in lights])
    logs = np.array([np.log(np.maximum(score(directions), 1e-3)) for door in strips for score in door])
    mean = logs.mean(axis=0)
    out = {light: float(m) for light, m in zip(lights, mean, strict=True)}
    if progress is not None:
        for k, (light, m) in enumerate(out.items()):
            progress(f"light [{light[0]:+.0f}, {light[1]:+.0f}] deg: {m:.3f} ({k + 1} of {len(lights)})")
    return out


def scores_under(strips: Sequence[Sequence[StripScore]], light: tuple[float, float]) -> list[float | None]:
    """Each door's mean log misfit ratio over its rounded strips (``strips``, per door) under one light,
    ``light`` ([azimuth, elevation] deg, cell frame); None for a door without a strip."""
    return [_scores([door], [light])[light] if door else None for door in strips]


def light_from_strips(
    strips: Sequence[Sequence[StripScore]],
    *,
    azimuths: Sequence[float] = COARSE_AZIMUTHS,
    elevations: Sequence[float] = COARSE_ELEVATIONS,
    fine_steps: int = 2,
    diffuse_share: float = DIFFUSE_SHARE,
    progress: Callable[[str], None] | None = None,
) -> LightMeasurement:
    """The direction of the light from rounded strips, ``strips`` (per door, its strips' scores).

    The mean log misfit ratio over the strips at every ``azimuths`` x ``elevations`` direction (deg, cell
    frame), then on a grid a quarter of its steps wide around the least, ``fine_steps`` of them each way.
    ``diffuse_share``: the share of the first grid's directions scoring alike (``RUNNER_UP_MARGIN``)
    beyond which no direction is stated (1 or more: the best is always stated). ``progress`` hears a
    line for each direction scored.

    Raises
    ------
    LightNotMeasurable
        No strip at all, or the strips fit more than ``diffuse_share`` of the directions about alike.
    """
    doors, n_strips = sum(1 for d in strips if d), sum(len(d) for d in strips)
    if n_strips == 0:
        raise LightNotMeasurable(
            "locate fitted no rounded arris strip on these images: they cannot tell the light "
            "(check that the doors are in the fixture and their recipes' arris_mm)"
        )
    coarse = [(float(a), float(e)) for e in elevations for a in azimuths]
    scores = _scores(strips, coarse, progress)
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
    scores.update(_scores(strips, fine, progress))
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
        strips=n_strips,
        doors=doors,
        runner_up_deg=runner,
        runner_up_score=scores[runner] if runner is not None else None,
        alike_share=alike / len(coarse),
        rivals=_rivals(scores, azimuths, elevations, best),
    )


def _rivals(
    scores: dict[tuple[float, float], float],
    azimuths: Sequence[float],
    elevations: Sequence[float],
    best: tuple[float, float],
) -> tuple[tuple[float, float], ...]:
    """:attr:`LightMeasurement.rivals` from the scores of the first grid (``azimuths`` x ``elevations``) and
    the best direction found."""
    A, E = len(azimuths), len(elevations)
    grid = np.array([[scores[(float(a), float(e))] for a in azimuths] for e in elevations])  # (E, A)
    minima = []
    for j in range(E):
        for i in range(A):
            around = grid[max(j - 1, 0) : j + 2, max(i - 1, 0) : i + 2]
            d = (float(azimuths[i]), float(elevations[j]))
            if grid[j, i] <= around.min() and directions_apart_deg(best, d) >= RUNNER_UP_APART_DEG:
                minima.append(d)
    return tuple(sorted(minima, key=scores.__getitem__)[:RIVALS_SOUGHT])


def finer_light(
    strips: Sequence[Sequence[StripScore]],
    first: LightMeasurement,
    progress: Callable[[str], None] | None = None,
) -> LightMeasurement:
    """``first`` (:func:`light_from_strips` over ``strips``, per door) sought again a quarter as finely: its
    search again with ``FINER_GRID_DEG`` apart about its best, then its quarter steps two each way (1.25
    deg, to 7.5 deg off it); and each of ``first.rivals``, sought as ``first`` was (a grid
    ``RIVAL_GRID_DEG`` apart about it and its quarter steps) and then as finely. The least of them, its
    score, and the larger doubt of its finest search and of the wider one that found it (at least
    ``MEASURED_SIGMA_FLOOR_DEG``); the runner-up another
    of them within ``RUNNER_UP_MARGIN``, ``RUNNER_UP_APART_DEG`` or more away (or none); ``progress`` as
    :func:`light_from_strips`'.

    Why: a lamp low beside the door leaves a terminator on every rounding, and the misfit climbs steeply
    within a few degrees of its direction. On a rendered cell lit from (-62.8, -13.7) deg the first search's
    best, (-60, -15), scored 0.20 over eight doors; sought again, (-62.5, -13.75) at 0.024 (and, read with
    exponents 10-20 % off the camera's, 0.04-0.11 where the first search's scores were 0.21-0.24: the valley
    the response measurement reads, :mod:`doorloc.vision.cell_response`). And the lamp's own valley may be
    the narrower of two: a cell lit from (52.7, 31.0) deg scored its mirror (-60, 20) 0.17 and (60, 20) 0.30
    on the first grid, and the first search stated the mirror (0.041, 0.027 sought again), while the lamp's
    side, sought again, scores 0.011."""
    # each valley's finest search, and the doubt of the wider search that found it (the finest one's own
    # reaches only 3.5 deg, where the first search's may say the valley is wider)
    found = [(_finer(strips, first.direction_deg, FINER_GRID_DEG, progress), first.sigma_deg)]
    for rival in first.rivals:
        near = _finer(strips, rival, RIVAL_GRID_DEG, progress)
        found.append((_finer(strips, near.direction_deg, FINER_GRID_DEG, progress), near.sigma_deg))
    best, wide_sigma = min(found, key=lambda f: f[0].score)
    others = [
        m
        for m, _ in found
        if directions_apart_deg(best.direction_deg, m.direction_deg) >= RUNNER_UP_APART_DEG
        and m.score <= best.score + RUNNER_UP_MARGIN
    ]
    runner = min(others, key=lambda m: m.score) if others else None
    return replace(
        first,
        direction_deg=best.direction_deg,
        score=best.score,
        sigma_deg=max(best.sigma_deg, wide_sigma),
        runner_up_deg=runner.direction_deg if runner is not None else None,
        runner_up_score=runner.score if runner is not None else None,
    )


def _finer(
    strips: Sequence[Sequence[StripScore]],
    about: tuple[float, float],
    step: float,
    progress: Callable[[str], None] | None,
) -> LightMeasurement:
    """:func:`light_from_strips` on the 3 x 3 grid ``step`` deg apart about ``about`` and its quarter steps
    two each way, every direction stated."""
    a, e = about
    return light_from_strips(
        strips,
        azimuths=(a - step, a, a + step),
        elevations=(max(e - step, -89.0), e, min(e + step, 89.0)),
        diffuse_share=math.inf,
        progress=progress,
    )


def light_of_one_door(strips: Sequence[StripScore], fine_steps: int = 2) -> LightMeasurement | None:
    """The light one door's rounded strips fit best (``locate.light_from_door``), stated even where they
    fit most directions about alike (any of them shades the strips as well); there the answer found under
    it also carries the free shadings' reading (:attr:`LightMeasurement.tells_one_direction`,
    ``doorloc.vision.locate``), since the turns of ``sigma_deg`` do not reach the other directions. None
    where the door has no rounded strip. ``fine_steps``: :func:`light_from_strips`' (a door's strips
    scored for an exponent or against the doors' common light take 1, ``strip_response.ARC_FINE_STEPS``)."""
    if not strips:
        return None
    return light_from_strips([list(strips)], fine_steps=fine_steps, diffuse_share=math.inf)
