"""The door's direction voted by each line's whole doubt (after the doubts stage, before the gate).

The joint line fit (:func:`doorloc.vision.lines.fit_rectangle_edges`) weighs each line's direction by the
spread of its points: right where the points' noise is all a line's doubt. Wood grain along the door's
height wanders along the arrises and tilts each by its own amount, JPEG blocks tilt a line at a small angle
to them, and an arris strip's shading can tilt it too: those doubts (:class:`doorloc.vision.uncertainty.
EdgeModelTerms`) differ from line to line, and a line in more doubt should count for less. Here each line's
direction weighs the inverse of its whole variance (its points' noise and its edge-model tilt), the pose
follows, and the budget weighs the lines' tilts the same way (:attr:`doorloc.vision.state.Refined.
direction_votes`).

The lines must be parallel (the arrises) or square to them (the bottom end): where their own directions
disagree about the voted one by more than their doubts allow, those doubts are too small, and
:func:`direction_spread` widens each voting line's by the Birge ratio (the spread's chi-square over its
degrees of freedom), as metrology combines measurements that disagree beyond their stated errors. The
voted direction does not move (every line's variance grows by the same factor); the yaw's uncertainty does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from doorloc.vision.jit import kernel
from doorloc.vision.lines import revote_direction
from doorloc.vision.metric import pose_from_fit
from doorloc.vision.region import SearchRegion
from doorloc.vision.state import Refined
from doorloc.vision.uncertainty import EDGE_MODEL_FLOOR_PX, EdgeModelTerms, LineDoubt, LineLever

__all__ = [
    "NOISE_ONLY_SHARE",
    "DirectionSpread",
    "birge_widening",
    "direction_spread",
    "direction_votes",
    "voted_by_doubts",
]


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
    return _votes(_direction_variances(r, model))


def _votes(variances: _Variances | None) -> dict[str, float]:
    """:func:`direction_votes` from the lines' direction variances (:func:`_direction_variances`)."""
    if variances is None:
        return {}
    noise, tilt, floor = variances
    if all(tilt[k] <= NOISE_ONLY_SHARE * noise[k] for k in noise):
        return {}
    if all(noise[k] + tilt[k] <= floor[k] for k in noise):
        return {}
    return {k: 1.0 / (noise[k] + tilt[k]) for k in noise}


def voted_by_doubts(
    r: Refined, region: SearchRegion, model: EdgeModelTerms
) -> tuple[Refined, DirectionSpread | None]:
    """``r`` with the door's direction voted by :func:`direction_votes` (the offsets, the pose and the
    direction's standard error with it; ``r`` as it is where there are no votes), and the voting lines'
    disagreement about it (:func:`direction_spread`). The lines' direction variances are read once for
    both (the vote keeps the fit's robust weights and residual scale, which they rest on)."""
    variances = _direction_variances(r, model)
    votes = _votes(variances)
    if votes:
        fit = revote_direction(r.fit, r.plane_points, votes)
        r = replace(r, fit=fit, pose=pose_from_fit(fit, region.face_map), direction_votes=votes)
    return r, direction_spread(r, model, variances)


#: per voting line the variance of its direction from its points' noise and from its edge-model tilt, and
#: the floor's (px per px, squared: :func:`_direction_variances`)
_Variances = tuple[dict[str, float], dict[str, float], dict[str, float]]


def _direction_variances(r: Refined, model: EdgeModelTerms) -> _Variances | None:
    """Per voting line (the far arris unless a far face lies beside it) the variance of its direction (px
    per px across, squared) from its points' noise (the fit's residual scale over their spread) and from
    its edge-model tilt, and the floor's (:data:`doorloc.vision.uncertainty.EDGE_MODEL_FLOOR_PX` over its
    length, twice); None where a line has no spread."""
    sc = r.pose.scale_mm_per_px
    noise_px = r.fit.scale / sc if sc > 0 else math.nan
    noise, tilt, floor = {}, {}, {}
    for k in ("reference", "bottom") if r.far_beside else ("reference", "bottom", "far"):
        s = r.samples[k]
        inl = (r.fit.weights[k] > 0) & np.isfinite(s.along)
        lever = LineLever.of_points(s.scan[inl], 0.0, 1.0)
        if not (lever.spread_px2 > 0 and noise_px > 0):
            return None
        noise[k], tilt[k] = noise_px**2 / lever.spread_px2, model.tilt(k) ** 2
        floor[k] = (2.0 * EDGE_MODEL_FLOOR_PX / max(lever.extent_px, 1.0)) ** 2
    return noise, tilt, floor


@dataclass(frozen=True)
class DirectionSpread:
    """How far the voting lines' own directions lie from the door's (``departures``: px across per px
    along, each line's own fit through its inlier points against the voted direction), the spread's
    chi-square over its degrees of freedom (``ratio2``: each departure over its line's direction doubt,
    squared, summed, over the lines less one), and the doubts that widen each line's direction by the
    ratio where it exceeds 1, and place a line that itself departs beyond its doubt by its drift
    (``doubts``: source ``direction``; empty where the ratio is 1 or less)."""

    ratio2: float
    departures: dict[str, float]
    doubts: tuple[LineDoubt, ...] = ()

    def figure(self) -> dict:
        """The diagnostics' account (``diagnostics.direction_spread``)."""
        return {
            "ratio2": round(self.ratio2, 4),
            "departures": {k: float(f"{v:.3e}") for k, v in self.departures.items()},
        }


def direction_spread(
    r: Refined, model: EdgeModelTerms, variances: _Variances | None = None
) -> DirectionSpread | None:
    """The voting lines' disagreement about the door's direction (:class:`DirectionSpread`), after the vote
    (``r``'s fit), against their doubts (their points' noise and ``model``'s tilts); None where a line has
    no spread or too few points (10) to fit its own direction.

    Where the ratio exceeds 1 each voting line's direction variance is widened by it: a ``direction``
    doubt of tilt ``sqrt((ratio2 - 1) (noise + tilt^2))``, and across the line, where the line itself
    departs beyond its doubt, its drift's RMS over its length, ``|departure| length / sqrt(12)`` px.
    Built on a door under 20 % grain whose stripes ran off its reference arris (``bench_surfaces.py --sets
    grain_strong --n 40 --seed 20100``, door 13): that arris's points drifted 3.2 px over its length, its
    own direction 0.26 deg off the truth and 0.2 deg off the far arris's, where its tilt doubt said 0.06
    deg; the ratio read 2.16, and the door, answered 0.33 mm off in x at 4.4 sigma, is refused
    ``uncertain``. Over 160 plain doors of the surfaces bench's grain, thin, strong-grain and hard sets
    (seed 20100) the ratio's median was 0.13 and its 90th percentile 0.48: the lines' doubts are generous;
    over 360 doors at three seeds it passed 1 on nine (docs/benchmarks.md, 2026-12-06).

    ``variances``: the lines' direction variances where the caller has read them already
    (:func:`voted_by_doubts`, for its vote); else they are read here."""
    variances = _direction_variances(r, model) if variances is None else variances
    if variances is None:
        return None
    noise, tilt, _ = variances
    sc = r.pose.scale_mm_per_px
    departures, extents = {}, {}
    for k in noise:
        s = r.samples[k]
        n, slope, extent = _own_slope(s.scan, s.along, r.fit.residuals[k], r.fit.weights[k], sc)
        if n < 10:
            return None
        departures[k], extents[k] = slope, extent
    whole = {k: noise[k] + tilt[k] for k in noise}
    ratio2, widen = birge_widening(departures, whole)
    if not ratio2 > 1.0:
        return DirectionSpread(ratio2, departures)
    # A line that itself departs beyond its doubt had its points drawn off the edge by what tilted it, by
    # the drift's RMS over its length at least, and the part of that which is the same all along it does
    # not show as tilt: its place is in doubt by as much.
    drift = {
        k: abs(d) * extents[k] / math.sqrt(12.0) if d * d > whole[k] else 0.0 for k, d in departures.items()
    }
    more = tuple(LineDoubt("direction", k, drift[k], tilt=widen[k]) for k in departures)
    return DirectionSpread(ratio2, departures, more)


def birge_widening(
    departures: dict[str, float], variances: dict[str, float]
) -> tuple[float, dict[str, float]]:
    """The Birge ratio of measurements ``departures`` from their common value with ``variances`` (the chi-square
    over the measurements less one), and per measurement the 1-sigma to add in quadrature so that each
    variance grows by the ratio where it exceeds 1 (0 where it does not): afterwards the measurements agree
    within their widened doubts, the ratio 1.

    >>> r2, add = birge_widening({"a": 3.0, "b": -3.0}, {"a": 1.0, "b": 1.0})
    >>> r2, round(add["a"] ** 2 + 1.0, 9)
    (18.0, 18.0)
    """
    chi2 = sum(d * d / variances[k] for k, d in departures.items())
    ratio2 = chi2 / max(len(departures) - 1, 1)
    grow = max(ratio2 - 1.0, 0.0)
    return ratio2, {k: math.sqrt(grow * variances[k]) for k in departures}


def _own_slope_warm_up(k) -> None:
    k(np.arange(20), np.zeros(20), np.zeros(20), np.ones(20), 0.2)


@kernel(_own_slope_warm_up)
def _own_slope(scan, along, residual_mm, weight, scale_mm_per_px):
    """A line's own direction against the fit's: over its inlier points (weight above 0, ``along`` and the
    residual finite), their count, the least-squares slope of their residuals (px) on their scan lines (px
    per px; 0 where they share one) and the scan lines' extent (px). Compiled: it runs on every line of
    every frame, and numpy's masks and copies for three lines cost 0.1 ms."""
    n = 0
    ms = 0.0
    mr = 0.0
    lo = np.inf
    hi = -np.inf
    for i in range(scan.size):
        if weight[i] > 0 and np.isfinite(along[i]) and np.isfinite(residual_mm[i]):
            n += 1
            ms += scan[i]
            mr += residual_mm[i] / scale_mm_per_px
            lo = min(lo, scan[i])
            hi = max(hi, scan[i])
    if n == 0:
        return 0, 0.0, 0.0
    ms /= n
    mr /= n
    sxy = 0.0
    sxx = 0.0
    for i in range(scan.size):
        if weight[i] > 0 and np.isfinite(along[i]) and np.isfinite(residual_mm[i]):
            ds = scan[i] - ms
            sxy += ds * (residual_mm[i] / scale_mm_per_px - mr)
            sxx += ds * ds
    return n, (sxy / sxx if sxx > 0 else 0.0), float(hi - lo)
