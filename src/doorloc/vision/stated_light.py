"""The cell's light as its file states it, and the rules for when a rounding's strip may be shaded under it.

``locate.light_direction_deg`` and ``locate.light_direction_sigma_deg`` become a :class:`StatedLight`;
:func:`doorloc.vision.arris_model.fit_strip_profile` shades a rounding's strip under it
(:func:`doorloc.vision.arris_strip.lit_basis`) where :func:`stated_light_explains` lets it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.pose import directions_across

__all__ = ["STATED_LIGHT_MISFIT_RATIO", "StatedLight", "stated_light_explains"]

#: most misfit of a rounding's shading under the cell's stated light over its free shading's for the
#: stated light to be used on that strip (beyond it the strip is fitted as where no light is stated). A
#: light stated right fits within 1.15 times the free shading's misfit on 90 of the 93 strips of the arris
#: bench's round set (seed 8100, 31 doors), within 1.42 on all (a 2.7 mm rounding's); stated 110 deg off,
#: most strips 2-100 times. A light far off that still fits is not caught here: what keeps it honest is the
#: doubt of its turns and the strip's posterior over both its readings (strip_posterior.valley_posterior)
STATED_LIGHT_MISFIT_RATIO = 2.0


def stated_light_explains(misfit_over_free: float) -> bool:
    """Whether a rounding's misfit under the stated light, over its free shading's, lets the light be used."""
    return misfit_over_free <= STATED_LIGHT_MISFIT_RATIO


@dataclass(frozen=True)
class StatedLight:
    """The cell's light as its file states it (``locate.light_direction_deg``): ``direction_cell`` a unit
    vector towards it (cell frame), and ``sigma_rad`` how far the true direction may lie from it, 1 sigma,
    radians, any way round (``locate.light_direction_sigma_deg``)."""

    direction_cell: np.ndarray
    sigma_rad: float = 0.0

    def turned(self) -> tuple[np.ndarray, ...]:
        """The stated direction turned by ``sigma_rad`` four ways (up and down, to either side): the mean
        square of what a strip's fit moves between them is what a direction off by ``sigma_rad`` the
        other way round moves it by, on average over the ways. Empty where the direction is exact."""
        if self.sigma_rad <= 0.0:
            return ()
        d = np.asarray(self.direction_cell, float)
        side, up = directions_across(d)
        c, s = math.cos(self.sigma_rad), math.sin(self.sigma_rad)
        return tuple(c * d + s * k * axis for axis in (side, up) for k in (1.0, -1.0))
