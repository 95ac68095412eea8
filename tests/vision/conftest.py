"""Shared fixtures of the vision tests."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from doorloc.cell import DoorSize
from doorloc.vision.edge_models import PassSettings


@pytest.fixture
def pass_settings() -> Callable[..., PassSettings]:
    """What one refine pass tells the edge models, for a plain 50 mm door read on every scan line, no arris
    and no step fit, with the keywords given changed."""

    def make(**kw) -> PassSettings:
        base = dict(
            every=1,
            sharp=False,
            optical_blur_px=float("nan"),
            slope_smooth=0,
            door=DoorSize(900, 50, 2100),
            arris=None,
            step_blur_px={},
        )
        return PassSettings(**(base | kw))  # type: ignore[arg-type]

    return make
