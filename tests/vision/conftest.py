"""Shared fixtures of the vision tests."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from doorloc.cell import DoorSize
from doorloc.sim.effects import Effects
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


@pytest.fixture
def dark_rounding() -> Callable[..., Effects]:
    """The renderer's effects for a rounded arris as dark as the background under ambient light alone (the
    arris bench's ``dark`` and ``focused_dark`` sets): hinge face and strip albedos, the ambient light, the
    blur (px), the read noise (grey levels) and the camera's exponent."""

    def make(
        hinge: float, dark: float, ambient: float, blur_px: float, noise_dn: float, gamma: float
    ) -> Effects:
        return Effects(
            arris_profile="round",
            albedo_hinge=hinge,
            albedo_chamfer=dark,
            albedo_background=dark,
            light_ambient=ambient,
            light_directional=0.0,
            blur_sigma_px=blur_px,
            read_noise_dn=noise_dn,
            gamma=gamma,
        )

    return make
