"""Is a plain edge's transition a blurred step's at all? Its overshoot beyond both plateaus.

A step blurred by any even spread and recorded through a power-law response overshoots neither of its
plateaus, in linear light or at any other exponent (raising to a power keeps the order of the levels). A
camera that sharpens its images (an unsharp mask on the grey levels) overshoots both, and the exponent that
makes such a transition symmetric is no camera's: the response check
(:mod:`doorloc.vision.response_check`) does not let the reading of an edge that overshoots replace the
cell's exponent (:func:`line_overshoot`).
"""

from __future__ import annotations

import numpy as np

from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.response import RESPONSE_MAX_PROFILES, line_transitions
from doorloc.vision.response_asymmetry import RESPONSE_PLATEAU_PX, Transitions

__all__ = ["OVERSHOOT_FROM_PX", "OVERSHOOT_MIN_BIN", "line_overshoot", "transition_overshoot"]


#: px from the sub-pixel edge beyond which :func:`transition_overshoot` looks for the mean transition beyond
#: its plateaus (a blurred step's own transition reaches them from inside, within noise)
OVERSHOOT_FROM_PX = 1.0
#: profiles a half-pixel bin of :func:`transition_overshoot` needs to count
OVERSHOOT_MIN_BIN = 10


def transition_overshoot(t: Transitions, g: float) -> float:
    """How far the profiles' mean transition, raw levels raised to ``g`` and each profile normalised by its
    plateaus (the mean of ``RESPONSE_PLATEAU_PX`` pixels at each end: 0 on the first end, 1 on the last),
    rises above its last plateau beyond ``OVERSHOOT_FROM_PX`` on that side of the edge and falls below its
    first on the other: the smaller of the two, a fraction of the step; NaN where fewer than 10 profiles
    have two distinct plateaus.

    Each side's figure is the largest over half-pixel bins of the distance from the edge (between the
    plateaus, ``OVERSHOOT_MIN_BIN`` profiles or more) of the bin's mean less twice its standard error over
    the profiles: noise alone rarely lifts it above 0. A step blurred by any even spread and recorded
    through a power-law response overshoots neither plateau in linear light, nor at any other exponent
    (raising to a power keeps the order of the levels); a camera that sharpens (an unsharp mask on the
    grey levels) overshoots both, whose transition is then made symmetric by an exponent that is no
    camera's (a 1.85 camera sharpened by 0.36 at 2 px read 1.12 +- 0.02, overshooting by 3 % of its step
    on both sides). JPEG's ringing beside a sharp edge and grain along it lift it a little.
    """
    pk = RESPONSE_PLATEAU_PX
    W = t.raw.shape[1]
    light = np.power(t.raw, g)
    lo, hi = light[:, :pk].mean(axis=1), light[:, W - pk :].mean(axis=1)
    span = hi - lo
    ok = np.abs(span) > 1e-9
    if int(ok.sum()) < 10:
        return float("nan")
    inner = slice(pk, W - pk)
    n = (light[ok, inner] - lo[ok, None]) / span[ok, None]
    d = t.offset[ok, None] + np.arange(pk, W - pk)[None]
    sides = []
    for beyond, excess in ((d >= OVERSHOOT_FROM_PX, n - 1.0), (d <= -OVERSHOOT_FROM_PX, -n)):
        if not beyond.any():
            return float("nan")
        b = np.floor(2.0 * d[beyond]).astype(np.int64)
        b -= b.min()
        v = excess[beyond]
        count = np.bincount(b)
        use = count >= OVERSHOOT_MIN_BIN
        if not use.any():
            return float("nan")
        c = np.maximum(count, 1)
        mean = np.bincount(b, v) / c
        var = np.maximum(np.bincount(b, v * v) / c - mean * mean, 0.0)
        lower = mean - 2.0 * np.sqrt(var / np.maximum(count - 1, 1))
        sides.append(float(lower[use].max()))
    return min(sides)


def line_overshoot(
    plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int, gamma: float, blur_px: float = 0.0
) -> float:
    """:func:`transition_overshoot` of one plain edge's profiles, linearised with ``gamma`` (its reading): the
    profiles and the window that :func:`doorloc.vision.response.fit_line_response` reads (its arguments);
    NaN where too few. Read only where a reading would replace the cell's exponent, not on every edge."""
    read = line_transitions(plane, samples, mask, half, blur_px)
    return (
        float("nan") if read is None else transition_overshoot(read[0].at_most(RESPONSE_MAX_PROFILES), gamma)
    )
