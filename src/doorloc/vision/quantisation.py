"""What the image's grey-level quantisation leaves on an edge where no noise dithers it.

The area estimator reads an edge's place from the grey levels of its window, each rounded to the image's
levels: half a level on each pixel is up to about ``sqrt(window / 12)`` levels on the window's sum, which
moves the edge by that over the edge's step. Sensor noise of half a level or more dithers the rounding, and
the error averages away along the line like noise. Without it (a render, or a camera that denoises before it
stores) the rounding repeats over every scan line where the edge keeps its phase and the plateau levels keep
their rounding: a door nearly square to the pixels, whose levels drift with the vignetting, is read in runs
of hundreds of scan lines, each a fixed fraction of a level off. The line's own standard error takes its
residuals as independent and claims almost nothing; the runs tilt it.

Measured (bench_jpeg_doors.py --no-noise, the PNG twins, 800 doors, steps 15-110 grey levels): a door 0.012
deg from square, step 32, vignetting 0.14, read its far arris in runs 1/32 px apart (one level over the step),
0.125 px from the same door without vignetting at one end, 0 at the other: yaw 0.0105 deg off at 6.5 sigma.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["QUANTISATION_DRIFT_TILT", "quantisation_doubt_px", "quantisation_tilt"]

#: offset doubts of tilt over a line's length the quantisation's runs give (as JPEG's drift at one phase:
#: the run's errors differ by about the doubt from one end of the line to the other)
QUANTISATION_DRIFT_TILT = 3.0


def quantisation_doubt_px(step_dn: float, window_px: int, noise_dn: float, level_dn: float = 1.0) -> float:
    """1-sigma (px) of the offset that rounding to levels of ``level_dn`` (0-255 scale: 1 for an 8-bit
    image, 255/65535 for a 16-bit one) leaves on an edge of ``step_dn`` read over ``window_px`` pixels,
    where the plateaus' noise is ``noise_dn``: ``sqrt(window / 12) level / |step|``, times what noise leaves
    of the rounding's bias (``exp(-2 pi^2 (noise / level)^2)``, the first harmonic of a rounding error
    smoothed by Gaussian noise: 0.17 at 0.3 levels, 0.007 at half a level). 0 where the step is unknown.

    Examples
    --------
    >>> round(quantisation_doubt_px(32.0, 7, 0.0), 4)
    0.0239
    >>> quantisation_doubt_px(32.0, 7, 1.0) < 1e-8
    True
    """
    step = abs(step_dn)
    if not (math.isfinite(step) and step > 0 and level_dn > 0):
        return 0.0
    noise = noise_dn / level_dn if math.isfinite(noise_dn) else 0.0
    return math.sqrt(window_px / 12.0) * level_dn / step * math.exp(-2.0 * math.pi**2 * noise**2)


def quantisation_tilt(doubt_px: float, scan: np.ndarray) -> float:
    """1-sigma tilt (px across per px along) the runs give a line of ``doubt_px`` whose points lie at
    ``scan``: ``QUANTISATION_DRIFT_TILT`` doubts over the line's length; 0 for fewer than two points."""
    if scan.size < 2 or not doubt_px > 0:
        return 0.0
    length = float(np.max(scan) - np.min(scan))
    return QUANTISATION_DRIFT_TILT * doubt_px / length if length > 0 else 0.0
