"""Is the camera response what the cell file says? A check on the shape of plain edges.

In linear light the transition of a plain step is the optical blur's edge response: symmetric about the
edge (a Gaussian or any even point-spread function). The area estimator puts the edge at the transition's
centre of mass; the 50 % crossing of the same transition lies there too. Grey levels that were linearised
with the wrong ``camera.response_gamma`` skew the transition: the crossing moves away from the centre of
mass, by about as much as the area estimate itself is biased. :func:`response_skew_px` measures that
distance on the aligned mean transition of many scan lines; locate reports it per line as
``response_sigma_mm`` (an edge-model doubt for the uncertainty budget).
"""

from __future__ import annotations

import numpy as np

from doorloc.vision.edges import EdgeSamples, _gather, oriented

__all__ = ["RESPONSE_DOUBT_FACTOR", "response_skew_px"]

#: edge bias per px of skew: on rendered sets with a gamma 1.8-2.2 camera read as linear the area estimate was
#: off by 10-21 times the skew (blur 0.6-1.5 px); the doubt reported is this multiple (it also inflates the
#: doubt of right answers by up to ~0.02 mm where the skew is noisy: a first, coarse check)
RESPONSE_DOUBT_FACTOR = 12.0


def response_skew_px(plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int,
                     lut: np.ndarray | None = None) -> float:
    """Distance (px) between the 50 % crossing and the centre of mass of the mean edge transition.

    The profiles (linearised by ``lut``) are aligned on their sub-pixel edge, normalised by their step and
    averaged on a 0.25 px grid. 0 for a symmetric transition (the response is right); NaN when no sample is
    usable.
    """
    m = mask & samples.valid
    if int(m.sum()) < 10:
        return float("nan")
    P = oriented(plane, samples.axis)
    e = samples.along[m]
    c0 = np.round(e).astype(int)
    vals, inside = _gather(P, samples.scan[m], c0 - half, 2 * half + 1, lut=lut)
    ok = inside.all(axis=1)
    if int(ok.sum()) < 10:
        return float("nan")
    g = np.diff(vals[ok].astype(np.float64), axis=1)
    tot = g.sum(axis=1, keepdims=True)
    good = np.abs(tot[:, 0]) > 1e-6
    g = g[good] / tot[good]
    pos = np.arange(2 * half) + 0.5 - half + (c0[ok][good] - e[ok][good])[:, None]
    bins = np.round(pos * 4).astype(int)
    lo = bins.min()
    acc = np.bincount((bins - lo).ravel(), weights=g.ravel())
    cnt = np.bincount((bins - lo).ravel())
    gm = np.where(cnt > 0, acc / np.maximum(cnt, 1), 0.0)
    if gm.sum() <= 0:
        return float("nan")
    x = (np.arange(gm.size) + lo) / 4.0
    w = gm / gm.sum()
    centre = float(np.sum(w * x))
    cum = np.cumsum(w) - 0.5 * w  # mass below each bin's centre
    k = int(np.searchsorted(cum, 0.5))
    if k <= 0 or k >= x.size:
        return float("nan")
    # the 50 % point between the bin centres k - 1 and k
    f = (0.5 - cum[k - 1]) / max(cum[k] - cum[k - 1], 1e-12)
    crossing = x[k - 1] + f * (x[k] - x[k - 1])
    return float(crossing - centre)
