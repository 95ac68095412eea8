"""The typed state that locate's stages pass on: each a frozen value, made by one stage and read by the next.

:class:`Refined` (the refine stage's edge points, fit and pose) -> :class:`ResponseCheck` (the response check:
the refined state the answer rests on, the camera response read off the image) -> :class:`EdgeDoubts` (the
doubts stage: every line's doubts and what the diagnostics report of them) -> the gate.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from doorloc.cell import Cell
from doorloc.vision import quality as q
from doorloc.vision.arris_model import StripFit
from doorloc.vision.edge_models import ReadersApart
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.far_band import FarFaceFit
from doorloc.vision.lines import RectangleFit
from doorloc.vision.metric import MetricPose
from doorloc.vision.response import (
    ResponseFit,
)
from doorloc.vision.strip_response import CellDisputed
from doorloc.vision.uncertainty import EdgeModelTerms

__all__ = ["EdgeDoubts", "Refined", "Refused", "ResponseCheck", "StageClock"]


@dataclass(frozen=True)
class Refined:
    """What the refine stage found: the sub-pixel edge points, their joint fit and the pose from it.

    Attributes
    ----------
    samples : dict[str, EdgeSamples]
        Edge points per line (``"bottom"``, ``"reference"``, ``"far"``).
    fit : RectangleFit
        The joint line fit.
    pose : MetricPose
        The pose from it.
    blur_px : float
        The transition width measured in the first pass, px (its optical blur: :func:`doorloc.vision.transition.blur_without_pixel`).
    half : int
        The final windows' half width, px.
    far_beside : bool
        Whether a far face was seen beside the far arris (the far line then measures only the thickness).
    far_fit : FarFaceFit or None
        The far-face model's fit, where it ran.
    step_fitted : dict[str, float]
        The lines whose points the blurred-step fit refined, and the blur it used, px.
    arris_fits : dict[str, tuple[StripFit, float]]
        Per line with an arris strip, its profile fit and the strip's width, px (read only).
    readers_apart : dict[str, ReadersApart]
        Per line where the blurred-step fit was tried, how far its points lay from the area estimator's,
        whichever of the two stands.
    plane_points : dict[str, tuple[ndarray, bool]]
        The joint fit's points per line, ``(X, Z)`` mm on the outline plane (0 where a point has none), and
        whether the line runs along door X.
    direction_votes : dict[str, float] or None
        Each voting line's weight on the door's direction where it was voted by the lines' doubts
        (:func:`doorloc.vision.direction_vote.voted_by_doubts`); None: by the spread of their points.
    face_sloped : dict[str, int]
        The lines of ``step_fitted`` whose face the fit took as sloped (texture along the edge:
        :func:`doorloc.vision.blurred_step.face_slope_step_fit`), and its window's half width, px.
    transition_widths_px : tuple[float, float]
        The first pass's transition widths of the bottom end and the reference arris, px (RMS, the pixel
        included; NaN where not read).
    """

    samples: dict[str, EdgeSamples]
    fit: RectangleFit
    pose: MetricPose
    blur_px: float
    half: int
    far_beside: bool
    far_fit: FarFaceFit | None
    step_fitted: dict[str, float]
    arris_fits: dict[str, tuple[StripFit, float]]
    readers_apart: dict[str, ReadersApart]
    plane_points: dict[str, tuple[np.ndarray, bool]]
    direction_votes: dict[str, float] | None = None
    face_sloped: dict[str, int] = field(default_factory=dict)
    transition_widths_px: tuple[float, float] = (math.nan, math.nan)


@dataclass(frozen=True)
class ResponseCheck:
    """What the response check stage found: the refined edges the answer rests on (read again with this
    image's camera exponent where it showed another than the cell's), the cell as used, the image's
    reading of the camera response (None where unchecked), per line, and its diagnostics; the image's
    plateau noise (0-255 scale, :func:`doorloc.vision.side_patches.plateau_noise_dn`; the doubts read it
    too)."""

    refined: Refined
    cell: Cell
    response: ResponseFit | None
    absorbed: bool
    diagnostics: dict[str, Any]
    plateau_noise_dn: float = 0.0


@dataclass(frozen=True)
class EdgeDoubts:
    """What the doubts stage found: every line's edge-model doubts, the figures the diagnostics report with
    them (``jpeg_block_ratio``, ``jpeg_quality``, ``arris_fit``, ``response_from_strips``), and where the door's rounded or
    chamfered strips rule out the cell's camera exponent, which the gate refuses (None: they do not, or
    were not read)."""

    model: EdgeModelTerms
    figures: dict[str, Any]
    response_disputed: CellDisputed | None = None


class Refused(Exception):
    """A stage's refusal of the image (:class:`doorloc.vision.quality.Refusal`) with its diagnostics: what
    locate answers with where a stage cannot go on."""

    def __init__(self, refusal: q.Refusal, **diag) -> None:
        super().__init__(refusal.message)
        self.refusal = refusal
        self.diag = diag


class StageClock:
    """Stage timings (ms) for the diagnostics; a stage run twice (the third pass of the fine stage, when a
    far face is in view, runs as ``edges2`` / ``fit2`` again) counts both runs."""

    def __init__(self) -> None:
        self.t = time.perf_counter()
        self.laps: dict[str, float] = {}

    def lap(self, name: str) -> None:
        t = time.perf_counter()
        self.laps[name] = round(self.laps.get(name, 0.0) + (t - self.t) * 1e3, 3)
        self.t = t
