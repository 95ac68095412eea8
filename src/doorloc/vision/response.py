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

__all__ = ["RESPONSE_DOUBT_FACTOR", "RESPONSE_SKEW_BLOCKS", "response_doubt_px", "response_skew_px"]

#: edge bias per px of skew: on rendered sets with a gamma 1.8-2.2 camera read as linear the area estimate was
#: off by 10-21 times the skew (blur 0.6-1.5 px); the doubt reported is this multiple (it also inflates the
#: doubt of right answers by up to ~0.02 mm where the skew is noisy: a first, coarse check)
RESPONSE_DOUBT_FACTOR = 12.0
#: contiguous blocks along the line over which the skew is measured again, for its standard error
RESPONSE_SKEW_BLOCKS = 8


def response_doubt_px(plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int,
                      lut: np.ndarray | None = None) -> tuple[float, float, float]:
    """The edge doubt (px) that the response check adds to one line, with the skew and its standard error.

    Texture and shading beside the edge (wood grain, a gradient, vignetting, JPEG blocks) skew the mean
    transition too, and differently along the line; that part of the skew says nothing about the response
    (and the texture's own bias is in the texture term). Its size is read from the skew's scatter over
    ``RESPONSE_SKEW_BLOCKS`` contiguous blocks of scan lines (contiguous: grain and shading vary slowly
    along the line), and only the skew beyond twice its standard error counts as the response's:
    ``RESPONSE_DOUBT_FACTOR * max(|skew| - 2 se, 0)``. A wrong response on a clean edge (small scatter)
    keeps nearly its full doubt.

    Returns
    -------
    (doubt_px, skew_px, se_px) : tuple of float
        NaN when the skew or its scatter cannot be measured (fewer than three usable blocks).
    """
    skew = response_skew_px(plane, samples, mask, half, lut)
    idx = np.flatnonzero(mask & samples.valid)
    n_blocks = min(RESPONSE_SKEW_BLOCKS, idx.size // 12)
    nan = float("nan")
    if not np.isfinite(skew) or n_blocks < 3:
        return nan, skew, nan
    per_block = []
    for block in np.array_split(idx, n_blocks):
        m = np.zeros(mask.shape, bool)
        m[block] = True
        per_block.append(response_skew_px(plane, samples, m, half, lut))
    b = np.asarray(per_block)
    b = b[np.isfinite(b)]
    if b.size < 3:
        return nan, skew, nan
    se = float(np.std(b, ddof=1) / np.sqrt(b.size))
    return RESPONSE_DOUBT_FACTOR * max(abs(skew) - 2.0 * se, 0.0), skew, se


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
    x = (np.arange(cnt.size) + lo) / 4.0
    filled = cnt > 0
    # Bins that no profile reached (an edge at few pixel phases fills only some of them) are not zero
    # transition: interpolate them from their neighbours (as zero they comb the mean transition and its
    # crossing moves by up to a bin's width).
    gm = np.interp(x, x[filled], acc[filled] / cnt[filled])
    if gm.sum() <= 0:
        return float("nan")
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
