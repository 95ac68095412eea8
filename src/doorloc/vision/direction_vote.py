"""The door's direction voted by each line's whole doubt (after the doubts stage, before the gate).

The joint line fit (:func:`doorloc.vision.lines.fit_rectangle_edges`) weighs each line's direction by the
spread of its points: right where the points' noise is all a line's doubt. Wood grain along the door's
height wanders along the arrises and tilts each by its own amount, JPEG blocks tilt a line at a small angle
to them, and an arris strip's shading can tilt it too: those doubts (:class:`doorloc.vision.uncertainty.
EdgeModelTerms`) differ from line to line, and a line in more doubt should count for less. Here each line's
direction weighs the inverse of its whole variance (its points' noise and its edge-model tilt), the pose
follows, and the budget weighs the lines' tilts the same way (:attr:`doorloc.vision.state.Refined.
direction_votes`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from doorloc.vision.lines import revote_direction
from doorloc.vision.metric import pose_from_fit
from doorloc.vision.region import SearchRegion
from doorloc.vision.state import Refined
from doorloc.vision.uncertainty import EDGE_MODEL_FLOOR_PX, EdgeModelTerms, LineLever

__all__ = ["NOISE_ONLY_SHARE", "direction_votes", "voted_by_doubts"]


#: the lines' edge-model tilts below this share of their points' noise leave the joint fit's weights standing
NOISE_ONLY_SHARE = 0.05


def direction_votes(r: Refined, model: EdgeModelTerms) -> dict[str, float]:
    """Each voting line's weight on the door's direction: the inverse variance of its direction (px per px
    across, squared), from its points' noise (the fit's residual scale over their spread) and its
    edge-model tilt. The far arris votes unless a far face lies beside it.

    Empty (the joint fit's weights stand) where a line has no spread, where every line's tilt is under
    :data:`NOISE_ONLY_SHARE` of its noise (the joint fit already weighs the lines so), or where every line's
    doubt is within the floor's tilt that the budget gives every line alike
    (:data:`doorloc.vision.uncertainty.EDGE_MODEL_FLOOR_PX` over its length, twice): a clean image's, no
    line's own to vote on (the rendered grid's lines reach 0.28 of it; a grained door's, several times it)."""
    sc = r.pose.scale_mm_per_px
    noise_px = r.fit.scale / sc if sc > 0 else math.nan
    noise, tilt, floor = {}, {}, {}
    for k in ("reference", "bottom") if r.far_beside else ("reference", "bottom", "far"):
        s = r.samples[k]
        inl = (r.fit.weights[k] > 0) & np.isfinite(s.along)
        lever = LineLever.of_points(s.scan[inl], 0.0, 1.0)
        if not (lever.spread_px2 > 0 and noise_px > 0):
            return {}
        noise[k], tilt[k] = noise_px**2 / lever.spread_px2, model.tilt(k) ** 2
        floor[k] = (2.0 * EDGE_MODEL_FLOOR_PX / max(lever.extent_px, 1.0)) ** 2
    if all(tilt[k] <= NOISE_ONLY_SHARE * noise[k] for k in noise):
        return {}
    if all(noise[k] + tilt[k] <= floor[k] for k in noise):
        return {}
    return {k: 1.0 / (noise[k] + tilt[k]) for k in noise}


def voted_by_doubts(r: Refined, region: SearchRegion, model: EdgeModelTerms) -> Refined:
    """``r`` with the door's direction voted by :func:`direction_votes` (the offsets, the pose and the
    direction's standard error with it); ``r`` as it is where there are no votes."""
    votes = direction_votes(r, model)
    if not votes:
        return r
    fit = revote_direction(r.fit, r.plane_points, votes)
    return replace(r, fit=fit, pose=pose_from_fit(fit, region.face_map), direction_votes=votes)
