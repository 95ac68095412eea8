"""The arris strip's brightness a priori, from physics: what places an edge where the image cannot.

A strip narrower than the blur shows its area, not how that area splits into its width and its level; the
prior on its radiance (a fraction of the hinge face's) is what decides there. The strip fit
(:func:`doorloc.vision.arris_model.fit_strip_profile`) takes it as a prior on the strip's deficit, and the
far-face and plain-edge models (:mod:`doorloc.vision.edge_models`) as one on its level.
"""

from __future__ import annotations

import math

__all__ = ["PRIOR_DEFICIT", "PRIOR_SIGMA", "STRIP_RADIANCE", "STRIP_RADIANCE_SIGMA", "deficit_prior"]

#: prior of the deficit where the two plateaus' radiances cannot say more (no contrast): a strip somewhere
#: between the background and the hinge face
PRIOR_DEFICIT, PRIOR_SIGMA = 0.5, 0.5
#: prior of the strip's mean radiance over the hinge face's (linear light): mean and standard deviation.
#: From physics, not fitted to any rendered set: the strip is the same wood turned away from the camera by
#: 0-90 deg. Under light from anywhere in front of the door a Lambertian surface turned by theta gets about
#: (1 + cos theta) / 2 of what the face gets: a 45 deg chamfer 0.85, a rounding (cos theta averaged over
#: its image width, uniform in sin theta) 0.89. A light from one side brightens one arris and darkens the
#: other; sanding and end grain move the albedo by some tens of per cent: +-0.45 (a grazing light can make
#: a chamfer facing it glint at twice the face, arris bench seed 1092: the prior's tail, where a strip
#: narrower than the blur is then misplaced by 2.7 sigma). It is what places the edge where the profiles
#: cannot split a strip's area into its width and its level (a strip narrower than the blur): the neutral
#: "between background and face" (0.5 +- 0.5 of the contrast) put the edge a quarter of such a strip's
#: width outwards on average (arris bench, arrises of 0-0.3 mm: thickness +0.047 mm mean over 12
#: chamfers) and, on a door darker than its background, assumed a strip brighter than the face.
STRIP_RADIANCE, STRIP_RADIANCE_SIGMA = 0.9, 0.45


def deficit_prior(face: float, background: float) -> tuple[float, float]:
    """The strip's deficit a priori, mean and standard deviation, from the plateaus' levels.

    ``face`` and ``background`` are in linear light (zero at black). A strip of radiance ``rho`` times the
    face's has the deficit ``(1 - rho) face / (face - background)``; ``rho`` is ``STRIP_RADIANCE +-
    STRIP_RADIANCE_SIGMA``. Without a usable contrast (or a face at black) the neutral ``PRIOR_DEFICIT +-
    PRIOR_SIGMA``.

    >>> [round(v, 3) for v in deficit_prior(200.0, 20.0)]  # a bright face on a dark background
    [0.111, 0.5]
    >>> [round(v, 3) for v in deficit_prior(100.0, 200.0)]  # a door darker than its background
    [-0.1, 0.45]
    >>> deficit_prior(0.0, 0.0)  # no contrast: the neutral prior
    (0.5, 0.5)
    """
    contrast = face - background
    if not (math.isfinite(face) and math.isfinite(background)) or face <= 0 or abs(contrast) < 1e-6 * face:
        return PRIOR_DEFICIT, PRIOR_SIGMA
    k = face / contrast
    return (1.0 - STRIP_RADIANCE) * k, STRIP_RADIANCE_SIGMA * abs(k)
