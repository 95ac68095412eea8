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

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.vision import light_search as ls
from doorloc.vision.light_search import LightMeasurement, LightNotMeasurable, StripScore
from doorloc.vision.locate import LocateTrace, locate

# (the measurement and its refusal are named here too: they are what a caller of measure_cell_light meets)
__all__ = ["LightMeasurement", "LightNotMeasurable", "measure_cell_light", "rounded_strips"]


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
    return ls.finer_light(strips, first, progress)
