"""The optical blur of a plain step: the far-face fit (:mod:`doorloc.vision.far_face`) without a band."""

from __future__ import annotations

import numpy as np

from doorloc.vision.edge_samples import EdgeSamples, ScanWindow
from doorloc.vision.far_band import FarBand
from doorloc.vision.far_face import subpixel_edges_far_face

__all__ = ["step_blur"]


def step_blur(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    plateau: int = 4,
    lut: np.ndarray | None = None,
    blur_px: float = 1.0,
    max_lines: int = 160,
) -> float:
    """Optical blur (Gaussian sigma, px, the pixel's own width not included) of a plain step edge.

    Each profile across the edge is modelled as a Gaussian-blurred step integrated over the pixels (the
    model of :func:`doorloc.vision.far_face.subpixel_edges_far_face` without a band) and the blur shared by
    all profiles is fitted with every edge position. Unlike :func:`doorloc.vision.transition.transition_width`
    this is not inflated by noise or texture. Returns NaN when no sample is usable.
    """
    idx = np.flatnonzero(mask & samples.valid)
    if idx.size == 0:
        return float("nan")
    keep = np.zeros(samples.scan.size, bool)
    keep[idx[:: max(idx.size // max_lines, 1)]] = True
    sub = samples.subset(keep)
    _, fit = subpixel_edges_far_face(
        ScanWindow(plane, sub.axis, sub.scan, sub.along, half, plateau, 1.0, lut, 0, -1),
        FarBand(np.full(sub.scan.size, -1.0), 0.0),
        blur_px=blur_px,
        fit_blur=True,
        n_iter=15,
    )
    return fit.blur_px
