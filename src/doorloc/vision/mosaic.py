"""A single-chip colour camera's raw Bayer mosaic given as a grey image: told apart, so that a refusal says so.

A camera set to deliver its raw sensor samples (BayerRG8, BayerRG12, ...) gives one channel in which each
2 x 2 block holds a red, two green and a blue filter's pixel. Read as grey, the door's edges are placed on
samples whose level jumps from pixel to pixel with the filter: locate refuses most such images for reasons
that send the operator looking for debris ("points do not lie on a straight line") and answers some (the
texture term takes the mosaic as texture: on three rendered doors of a camera in that mode, two refused
``edge_not_straight``, one answered 0.0007 mm off at 0.037 mm). The mosaic shows in the four pixel sites'
mean levels over the image: the two green sites, diagonal in the block, alike, and red and blue apart from
them (a rendered wood door: red +7.5 %, blue -14 % against green, the greens within 0.05 %). Any other
image's four sites agree: within 0.1 % on the rendered fixtures, within 0.4 % on the public board
photographs (Bouguet's, whose even and odd rows differ by 0.3 %). A camera that balances its raw channels
(red and blue within ``MOSAIC_CHANNELS_APART`` of green) shows none, and its image is read as grey.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MOSAIC_CHANNELS_APART", "MOSAIC_GREENS_ALIKE", "BayerMosaic", "bayer_mosaic"]

#: the two green sites' mean levels agree within this fraction of their mean
MOSAIC_GREENS_ALIKE = 0.01
#: the red and the blue sites' mean levels each lie at least this fraction of the greens' mean from it
MOSAIC_CHANNELS_APART = 0.03


@dataclass(frozen=True)
class BayerMosaic:
    """The mosaic a grey image shows: the red-or-blue sites' mean levels against the greens', as fractions
    (``first`` the site in the first row, ``second`` the one in the second)."""

    first: float
    second: float


def bayer_mosaic(image: np.ndarray) -> BayerMosaic | None:
    """The Bayer mosaic a single-channel image (``(H, W)`` or ``(H, W, 1)``, 8 or 16 bits) shows in its four
    pixel sites' mean levels (module docstring), or None: no mosaic, a colour image, or one too small or
    dark to tell (a site's mean under one grey level of 255)."""
    im = np.asarray(image)
    if im.ndim == 3 and im.shape[2] == 1:
        im = im[..., 0]
    if im.ndim != 2 or im.shape[0] < 4 or im.shape[1] < 4:
        return None
    h, w = im.shape[0] // 2 * 2, im.shape[1] // 2 * 2
    sites = [float(im[i:h:2, j:w:2].mean(dtype=np.float64)) for i in (0, 1) for j in (0, 1)]
    one_grey = 1.0 if im.dtype == np.uint8 else 257.0
    if min(sites) < one_grey:
        return None
    # the greens are the diagonal pair that agrees (RGGB, BGGR: the second; GRBG, GBRG: the first)
    (g1, g2), (c1, c2) = sorted(
        (((sites[0], sites[3]), (sites[1], sites[2])), ((sites[1], sites[2]), (sites[0], sites[3]))),
        key=lambda pair: abs(pair[0][0] - pair[0][1]),
    )[0]
    green = 0.5 * (g1 + g2)
    if abs(g1 - g2) > MOSAIC_GREENS_ALIKE * green:
        return None
    first, second = c1 / green - 1.0, c2 / green - 1.0
    if min(abs(first), abs(second)) < MOSAIC_CHANNELS_APART:
        return None
    return BayerMosaic(first, second)
