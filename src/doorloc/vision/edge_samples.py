"""What every edge reader reads, :class:`ScanWindow`, and the edge points it returns, :class:`EdgeSamples`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from doorloc.vision.sampling import Axis

__all__ = ["EdgeSamples", "ScanWindow"]


@dataclass(frozen=True)
class EdgeSamples:
    """Edge positions found on a set of scan lines.

    Attributes
    ----------
    axis : "col" or "row"
        Profiles run along columns (``scan`` = u, ``along`` = v) or rows (``scan`` = v, ``along`` = u).
    scan : ndarray (N,) int
        Scan-line coordinate.
    along : ndarray (N,) float
        Sub-pixel edge position on the scan line, px (NaN where none).
    step : ndarray (N,) float
        Signed grey-level step ``B - A`` across the edge in the direction of increasing ``along``, 0-255 scale.
    noise : ndarray (N,) float
        Grey-level spread on the plateaus (0-255 scale), a per-sample noise figure.
    width : ndarray (N,) float
        Reserved for a per-sample transition width, px (NaN: :func:`doorloc.vision.transition.transition_width` measures the
        width of a whole edge, which noise does not inflate).
    bright : ndarray (N,) float
        The brighter of the two plateau levels, 0-255 scale (saturation check).
    valid : ndarray (N,) bool
        Window inside the image and estimate finite.
    strip_contrast : ndarray (N,) float or None
        On an arris line (:func:`doorloc.vision.arris_lines.arris_edges`): the grey-level step (0-255, its
        size) of the strongest border of the strip's fitted shape that locates the point; None on an edge
        without a strip.
    """

    axis: Axis
    scan: np.ndarray
    along: np.ndarray
    step: np.ndarray
    noise: np.ndarray
    width: np.ndarray
    bright: np.ndarray
    valid: np.ndarray
    strip_contrast: np.ndarray | None = None

    def uv(self) -> np.ndarray:
        """Edge points as image ``(u, v)``, shape (N, 2)."""
        s = self.scan.astype(float)
        return np.stack([s, self.along], 1) if self.axis == "col" else np.stack([self.along, s], 1)

    def subset(self, mask: np.ndarray) -> EdgeSamples:
        return EdgeSamples(
            self.axis,
            self.scan[mask],
            self.along[mask],
            self.step[mask],
            self.noise[mask],
            self.width[mask],
            self.bright[mask],
            self.valid[mask],
            self.strip_contrast[mask] if self.strip_contrast is not None else None,
        )

    def located_contrast(self, polarity: int, enough: float) -> np.ndarray:
        """Per sample, the step that locates the edge, 0-255, signed by ``polarity`` (>0: the expected way).

        The door's step ``step`` where it alone is ``enough`` (the edges' least contrast) the expected way.
        On an arris line whose face hardly differs from the background, or is darker (a strip darker or
        brighter than both sides: a chamfer in shadow between a face and a background of one shade, a lit
        rounding beside a face in shadow), the strip's borders locate the point, not the face's step (the
        strip's shape is fitted with its levels free, whatever their order): there the stronger of the face's
        step and the strip's strongest border (``strip_contrast``). Whether a sample reaches a
        threshold up to ``enough`` is as for the stronger of the two everywhere. In the array type of
        ``step``.
        """
        c = polarity * self.step
        if self.strip_contrast is None:
            return c
        return np.where(c < enough, np.maximum(c, self.strip_contrast), c).astype(self.step.dtype, copy=False)


@dataclass(frozen=True)
class ScanWindow:
    """What every edge model reads.

    Attributes
    ----------
    plane : ndarray
        The luminance plane (grey levels).
    axis : "col" or "row"
        Profiles along image columns or rows (:func:`doorloc.vision.sampling.oriented`).
    scan, centre : ndarray (N,)
        The scan lines and the predicted edge on each, px.
    half : int
        The window's half width, px.
    plateau : int
        Plateau samples beside the window, px.
    scale_to_8bit : float
        Factor from the plane's grey levels to 0-255.
    lut : ndarray or None
        The table turning grey levels into linear light (:func:`doorloc.vision.sampling.linearizing_lut`).
    level_smooth : int
        Scan lines over which the plateau levels are averaged (0: none).
    door_side : int
        +1 where the door lies towards increasing ``along``, -1 towards decreasing.
    """

    plane: np.ndarray
    axis: Axis
    scan: np.ndarray
    centre: np.ndarray
    half: int
    plateau: int
    scale_to_8bit: float
    lut: np.ndarray | None
    level_smooth: int
    door_side: int

    @property
    def lines(self) -> tuple[np.ndarray, Axis, np.ndarray, np.ndarray, int]:
        """``(plane, axis, scan, centre, half)``: the arguments every estimator takes first."""
        return self.plane, self.axis, self.scan, self.centre, self.half
