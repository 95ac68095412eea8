"""What lies beside the far arris of a thin door whose far face is in view (:class:`FarBand`, the far-face
fit's input), and what the fit found there (:class:`FarFaceFit`, its output): the types
:func:`doorloc.vision.far_face.subpixel_edges_far_face` reads and writes, kept apart from the fit so that
the thickness check and the line fits read them without the fit's machinery.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FarBand", "FarFaceFit"]


@dataclass(frozen=True)
class FarFaceFit:
    """What :func:`doorloc.vision.far_face.subpixel_edges_far_face` found besides the edge points.

    Attributes
    ----------
    band_level : float
        The far face's grey level relative to the two sides, ``(L - A) / (B - A)`` (``A`` the hinge
        face, ``B`` the background): 0 when the band looks like the hinge face, 1 like the background,
        > 1 brighter than the hinge face on a dark background... (any real value).
    blur_px : float
        Optical blur (Gaussian sigma, px) that fits the profiles best.
    band_px : float
        Median band width over the valid scan lines, px.
    arris_sigma_px : float
        Median standard error of one arris point from the profile noise, px.
    model_sigma_px : float
        How far the arris moves if the band level were off by ``far_face.LEVEL_DOUBT`` or the blur by
        ``far_face.BLUR_DOUBT`` px (the two combined as independent errors; a blur that is off also pulls
        the fitted levels, whose move counts with it): the doubt the model leaves, which noise averaging
        does not reduce. Large where a narrow band cannot be told from the arris. With an arris strip, also
        by the strip level's doubt (its fitted standard error and ``far_face.LEVEL_DOUBT``).
    strip_level : float
        The arris strip's relative level ``(S - A) / (B - A)`` (NaN without a strip).
    other_reading_px : float
        Where the band's other reading puts the arris, px from this one, positive away from the hinge face
        (a thicker door); 0 where the band's level tells the two readings apart. A band about as bright as
        the background (level near 1) leaves one step, the arris; a band about as bright as the hinge face
        (near 0) leaves one step too, the far face's back edge: the same profile, read as a door a band
        thinner or thicker (see :data:`doorloc.vision.far_face.BAND_SIDE_LEVEL`).
    band_slope : float
        The band's change in width per px the arris moves away from the hinge face (a thicker door), px / px:
        the geometry's ``-(1 - k)``, ``k`` the ratio of the arris's depth to the far face's back edge's (about
        -0.7; :attr:`doorloc.vision.region.Track.band_slope`).
    other_fitted : str
        Where ``other_reading_px`` is a reading fitted to the profiles beside an arris strip, its misfit
        within :data:`doorloc.vision.far_face.READINGS_ALIKE` of this one's (not only a level the band shares
        with a side), what it reads the other way: ``"band"`` (the one step beside the far arris is the far
        face's back edge rather than the arris, or the reverse) or ``"strip"`` (the strip's border lies a
        strip's width away); ``""`` where it is not fitted. The thickness check weighs either kind however
        far it lies (within the door sizes doorloc accepts); one not fitted, on a door without arrises, the
        door's bottom end may settle (:mod:`doorloc.vision.bottom_end`).
    """

    band_level: float
    blur_px: float
    band_px: float
    arris_sigma_px: float
    model_sigma_px: float
    strip_level: float = float("nan")
    other_reading_px: float = 0.0
    band_slope: float = 0.0
    other_fitted: str = ""


@dataclass(frozen=True)
class FarBand:
    """What lies beside the far arris on the far side: the far face's band and, on a chamfered or rounded
    arris, the strip on the hinge-face side.

    Attributes
    ----------
    width_px : ndarray (N,)
        Predicted band width on each scan line at the window's predicted edge, px, signed: <= 0 where no
        band is in view (the far face seen edge-on or from behind).
    slope : float
        ``dw / de`` as the arris moves outwards (``-(1 - k)``, ``k`` the back edge's relative scale).
    strip_px : ndarray (N,) or None
        A chamfered or rounded far arris: the strip's width on the hinge-face side of ``e``, px (``e`` is
        then the far face's near border, where the strip meets it). The profile is ``hinge face A | strip S
        | far face L | background B``, the strip's relative level ``(S - A) / (B - A)`` one more shared
        unknown, with the prior that the strip's radiance is ``strip_radiance`` (mean, standard deviation)
        times the hinge face's (:data:`doorloc.vision.strip_prior.STRIP_RADIANCE`). Without it a strip
        took the far face's level or the hinge face's and the thickness was up to the strip's width off
        with a sigma that did not know it (thin doors with 0.5-3 mm arrises: 1.2 mm at 12 sigma).
    strip_radiance : (float, float)
        The strip's radiance over the hinge face's, prior mean and standard deviation.
    strip_shaded : bool
        The strip is a rounding, whose shading runs across it from the hinge face's level towards the far
        face's: its one fitted level is in doubt by that range's spread too.
    """

    width_px: np.ndarray
    slope: float
    strip_px: np.ndarray | None = None
    strip_radiance: tuple[float, float] = (0.9, 0.45)
    strip_shaded: bool = False
