"""What is known about each catalogue parameter before the data set is seen: its prior (1 sigma).

A model check weighs how well a cause fits the pose errors against how plausible its fitted value is:
a 0.7 % focal-length error explains a rounded arris's edge shifts about as well as the arris itself,
but no calibration is that far off (doorloc's own carry fx to about 0.05 %), and the extended cell it
would write moves every other door wrongly. Each parameter's prior is a zero-mean normal about the
cell's own value (``response_gamma``: about the cell's exponent) whose 1-sigma comes from:

- the camera calibration's covariance (``Cell.calibration_covariance``: fx, fy or f, cx, cy, k1) where the
  cell's calibration file carries one; otherwise the defaults below, those of a board calibration of the
  kind ``doorloc calibrate`` makes (fx to 0.05 %, fy/fx to 0.05 %, the principal point to 2 px);
- the cell's mount (extrinsics): a cell file carries no covariance of its mount, and a mount can be
  knocked or drift after the cell was measured, so its defaults are those of a mount checked on the
  shop floor (0.1 deg, 1 mm along the axis, 0.5 mm across);
- the door and fixture (arris, fixture depth) and a response never measured: broad, what any shop's doors
  and fixtures span.

A fitted value beyond :data:`IMPLAUSIBLE_SIGMAS` of its prior is reported as implausible: the data say
the cell is that far off, but a surrogate for a cause outside the model is the likelier reading.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from doorloc.cell import Cell
from doorloc.modelcheck.catalogue import Effect

__all__ = ["Prior", "priors_for", "IMPLAUSIBLE_SIGMAS", "DEFAULT_SIGMA", "prior_sigmas_away"]

#: A fitted value this many prior sigmas from the cell's own is implausible.
IMPLAUSIBLE_SIGMAS = 5.0

#: Default 1-sigma per parameter (the units of :class:`~doorloc.modelcheck.catalogue.Effect` params)
#: where neither the cell nor its calibration says better.
DEFAULT_SIGMA: dict[str, tuple[float, ...]] = {
    "camera_roll": (0.1,),  # deg
    "camera_tilt": (0.1, 0.1),  # deg
    "camera_distance": (1.0,),  # mm
    "lateral_offset": (0.5, 0.5),  # mm
    "focal_length": (0.05,),  # % of f
    "pixel_aspect": (0.05,),  # % of fy/fx
    "radial_distortion": (0.01,),  # k1 of a calibrated lens
    "arris": (1.5,),  # mm: sharp edges to a rounded 3 mm arris
    "fixture_depth": (0.05,),  # mm of face depth per mm of door width
    "response_gamma": (0.8,),  # exponent never measured: linear (1) to sRGB-like (2.2) and beyond
}
#: k1 of a lens whose calibration fixed the distortion at zero (no covariance, all coefficients 0): the
#: real lens's k1 was never measured, anything a machine-vision lens has is plausible
UNCALIBRATED_K1_SIGMA = 0.1
#: Default 1-sigma of the principal point (px) where the calibration carries none
DEFAULT_PRINCIPAL_POINT_PX = 2.0


@dataclass(frozen=True)
class Prior:
    """One effect's prior: 1-sigma per parameter (its units) about the cell's value, and where it came from."""

    sigma: tuple[float, ...]
    source: str

    def sigmas_away(self, offset: Sequence[float]) -> float:
        """The largest |offset| / sigma over the parameters."""
        return float(np.max(np.abs(np.asarray(offset, float)) / np.asarray(self.sigma, float)))


def _cov(cell: Cell) -> dict[str, float]:
    """Variances of the calibration's named parameters (and the fx-fy covariance as ``fx*fy``)."""
    C, names = cell.calibration_covariance, list(cell.calibration_covariance_names)
    if C is None or not names:
        return {}
    C = np.asarray(C, float)
    out = {n: float(C[i, i]) for i, n in enumerate(names)}
    if "fx" in names and "fy" in names:
        out["fx*fy"] = float(C[names.index("fx"), names.index("fy")])
    return out


def priors_for(cell: Cell, catalogue: Sequence[Effect]) -> dict[str, Prior]:
    """The prior of every effect in ``catalogue`` for ``cell`` (module docstring)."""
    var = _cov(cell)
    fx, fy = cell.camera.fx, cell.camera.fy
    out: dict[str, Prior] = {}
    for e in catalogue:
        sig, src = DEFAULT_SIGMA[e.name], "default"
        if e.name == "focal_length" and ("f" in var or "fx" in var):
            rel = (
                var["f"] / ((fx + fy) / 2) ** 2 if "f" in var else (var["fx"] / fx**2 + var["fy"] / fy**2) / 2
            )
            sig, src = (max(100 * float(np.sqrt(rel)), 1e-4),), "calibration covariance"
        elif e.name == "pixel_aspect" and "fx" in var and "fy" in var:
            rel = var["fx"] / fx**2 + var["fy"] / fy**2 - 2 * var["fx*fy"] / (fx * fy)
            sig, src = (max(100 * float(np.sqrt(max(rel, 0.0))), 1e-4),), "calibration covariance"
        elif e.name == "pixel_aspect" and "f" in var:
            sig, src = (1e-3,), "calibration fixed the aspect"
        elif e.name == "radial_distortion":
            if "k1" in var:
                sig, src = (max(float(np.sqrt(var["k1"])), 1e-5),), "calibration covariance"
            elif not np.any(np.asarray(cell.camera.dist_coeffs, float)):
                sig, src = (UNCALIBRATED_K1_SIGMA,), "distortion never calibrated (all zero)"
        elif e.name == "camera_tilt":
            # a principal-point error moves the image as a tilt does: its doubt, as an angle, adds in
            pp = [np.sqrt(var[n]) if n in var else DEFAULT_PRINCIPAL_POINT_PX for n in ("cy", "cx")]
            ang = [float(np.degrees(np.arctan(p / f))) for p, f in zip(pp, (fy, fx), strict=True)]
            sig = tuple(float(np.hypot(s, a)) for s, a in zip(DEFAULT_SIGMA[e.name], ang, strict=True))
            src = "mount default and the principal point's" + (
                " calibration covariance" if "cx" in var else " default"
            )
        elif e.name == "response_gamma" and cell.response_gamma_sigma is not None:
            sig, src = (float(cell.response_gamma_sigma),), "measured response"
        out[e.name] = Prior(tuple(float(s) for s in sig), src)
    return out


def prior_sigmas_away(prior: Prior, effect: Effect, value: Sequence[float], cell: Cell) -> float:
    """How many prior sigmas the fitted ``value`` lies from the cell's own (largest over parameters)."""
    return prior.sigmas_away(np.asarray(value, float) - effect.nominal(cell))
