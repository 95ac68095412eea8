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

__all__ = [
    "RESPONSE_DOUBT_FACTOR",
    "RESPONSE_SKEW_BLOCKS",
    "quantization_skew_px",
    "response_doubt_px",
    "response_skew_px",
]

#: edge bias per px of skew: on rendered sets with a gamma 1.8-2.2 camera read as linear the area estimate was
#: off by 10-21 times the skew (blur 0.6-1.5 px); the doubt reported is this multiple (it also inflates the
#: doubt of right answers by up to ~0.02 mm where the skew is noisy: a first, coarse check)
RESPONSE_DOUBT_FACTOR = 12.0
#: contiguous blocks along the line over which the skew is measured again, for its standard error
RESPONSE_SKEW_BLOCKS = 8


def quantization_skew_px(step_dn: float, noise_dn: float, blur_px: float) -> float:
    """The skew (px) that rounding the grey levels can make on its own, 1 sigma.

    Each plateau's level is rounded the same way on every scan line of an edge unless noise dithers it:
    the residual rounding error of a level under Gaussian noise ``noise_dn`` is at most
    ``exp(-2 pi^2 noise^2) / pi`` grey levels (the sawtooth's first Fourier term; 0.32 without noise,
    negligible above half a grey level). The two plateaus' errors (``sqrt 2`` of one) move the normalised
    transition's two tails by that much over the step, which moves its centre of mass against its 50 %
    crossing by about the transition's width (``2 blur + 1`` px) times that fraction.
    """
    if not (np.isfinite(step_dn) and step_dn > 0):
        return float("nan")
    level_err = min(0.5, float(np.exp(-2.0 * np.pi**2 * max(noise_dn, 0.0) ** 2)) / np.pi)
    return float(np.sqrt(2.0) * level_err / step_dn * (2.0 * max(blur_px, 0.0) + 1.0))


def response_doubt_px(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    lut: np.ndarray | None = None,
    blur_px: float = 0.0,
) -> tuple[float, float, float]:
    """The edge doubt (px) that the response check adds to one line, with the skew and its standard error.

    Texture and shading beside the edge (wood grain, a gradient, vignetting, JPEG blocks) skew the mean
    transition too, and differently along the line; that part of the skew says nothing about the response
    (and the texture's own bias is in the texture term). Its size is read from the skew's scatter over
    ``RESPONSE_SKEW_BLOCKS`` contiguous blocks of scan lines (contiguous: grain and shading vary slowly
    along the line), and only the skew beyond twice its standard error counts as the response's:
    ``RESPONSE_DOUBT_FACTOR * max(|skew| - 2 se, 0)``. The standard error also holds what rounding the
    grey levels can skew (:func:`quantization_skew_px`: a noise-free 8-bit image shows a skew of ~0.004 px
    on a linear camera, which no wrong response made). A wrong response on a clean edge (small scatter)
    keeps nearly its full doubt. ``blur_px`` is the optical blur sigma (px).

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
    quant = quantization_skew_px(
        *_plateau_step_and_noise(plane, samples, mask & samples.valid, half), blur_px
    )
    se = float(np.hypot(np.std(b, ddof=1) / np.sqrt(b.size), quant if np.isfinite(quant) else 0.0))
    return RESPONSE_DOUBT_FACTOR * max(abs(skew) - 2.0 * se, 0.0), skew, se


def response_skew_px(
    plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int, lut: np.ndarray | None = None
) -> float:
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


def _plateau_step_and_noise(
    plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int
) -> tuple[float, float]:
    """The step and the grey-level noise (raw grey levels) from the pixels just beyond the window.

    The noise from the same pixel on neighbouring scan lines (the samples' own noise comes from plateaus
    that may be one pixel wide; texture along the edge cancels in the difference, and texture across it
    dithers the rounding as noise does).
    """
    if int(mask.sum()) < 3:
        return float("nan"), 0.0
    P = oriented(plane, samples.axis)
    c0 = np.round(samples.along[mask]).astype(int)
    vals, inside = _gather(P, samples.scan[mask], c0 - half - 1, 2 * half + 3)
    ends = vals[inside.all(axis=1)][:, [0, -1]].astype(np.float64)
    if ends.shape[0] < 3:
        return float("nan"), 0.0
    step = float(np.median(np.abs(ends[:, 1] - ends[:, 0])))
    # an RMS, not a MAD: on rounded grey levels with under a grey level of noise most differences are 0
    # (a MAD of 0 would read as no dither at all); the largest tenth (edges of marks, grain) left out
    d = np.sort(np.abs(np.diff(ends, axis=0)).ravel())
    d = d[: max(int(0.9 * d.size), 1)]
    noise = float(np.sqrt(np.mean(d**2) / 2.0))
    return step, noise
