"""The locate result (shared/SPEC.md section 3): one JSON object per image.

The required fields are fixed by the product contract and are never renamed; everything that helps
a person judge the answer (per-line residuals, inlier counts, contrast, timings) goes beside them.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["LineQuality", "LocateResult", "PoseUncertainty", "Provenance"]


class PoseUncertainty(BaseModel):
    """1-sigma standard uncertainty of a reported pose (cell frame)."""

    x_mm: float = Field(description="standard uncertainty of x_mm, mm")
    z_mm: float = Field(description="standard uncertainty of z_mm, mm")
    yaw_deg: float = Field(description="standard uncertainty of yaw_deg, degrees")

    def widened(self, x_mm: float, z_mm: float, yaw_deg: float) -> PoseUncertainty:
        """This uncertainty with one more term (mm, mm, deg) added in quadrature."""
        return PoseUncertainty(
            x_mm=math.hypot(self.x_mm, x_mm),
            z_mm=math.hypot(self.z_mm, z_mm),
            yaw_deg=math.hypot(self.yaw_deg, yaw_deg),
        )


class Provenance(BaseModel):
    """Which software and which model produced an answer."""

    model_config = ConfigDict(extra="allow")

    version: str = Field(description="doorloc version")
    cell_sha256: str | None = Field(None, description="SHA-256 of the cell file's bytes")
    calibration_sha256: str | None = Field(
        None, description="SHA-256 of the camera calibration (file, or inline model)"
    )
    recipe_version: int | None = Field(
        None, description="version of the door recipe used, when a recipe was used"
    )


class PhysicalModel(BaseModel):
    """The cell's physical settings that shaped an answer (echoed so an answer says which model produced it)."""

    model_config = ConfigDict(extra="allow")

    response_gamma: float = Field(
        description="camera response the grey levels were linearised with (camera.response_gamma)"
    )
    response_gamma_sigma: float | None = Field(
        None,
        description="1-sigma of response_gamma where it was measured (camera.response_gamma_sigma, or doorloc "
        "batch from the job's rounded doors); null: stated, not measured",
    )
    stored_bits: int | None = Field(
        None,
        description="the bits a 16-bit image's levels were read at (camera.stored_bits: a 12-bit camera's "
        "0-4095 brought to the 16-bit scale); null: the image's own depth, 8 or 16 bits",
    )
    arris_mm: float = Field(description="arris size the edges were corrected for, mm (0: sharp edges)")
    arris_profile: str = Field(description="'chamfer' or 'round'")
    door_brighter: bool = Field(
        description="lighting side: the hinge face is brighter than the background (locate.door_brighter)"
    )
    face_y_mm: float | None = Field(
        None, description="hinge-face depth used for this door, mm (cell frame Y)"
    )
    light_direction_deg: list[float] | None = Field(
        None,
        description="the light, [azimuth, elevation] deg in the cell frame, that rounded arrises were shaded "
        "under: the cell's (locate.light_direction_deg) or the door's own (light_source); null: none, a free shading",
    )
    light_direction_sigma_deg: float | None = Field(
        None,
        description="how far that light may lie from the true one, 1 sigma, deg "
        "(locate.light_direction_sigma_deg, or the door's own light's doubt), carried into the rounded arrises' "
        "doubt; null: no light",
    )
    light_source: Literal["cell", "door"] | None = Field(
        None,
        description="where light_direction_deg came from: 'cell' (locate.light_direction_deg) or 'door' (sought "
        "from this door's own rounded strips, locate.light_from_door; diagnostics.door_light); null: none",
    )
    camera_photometry: dict[str, float] | None = Field(
        None,
        description="the camera's photometric model as locate used it (the calibration's, or "
        "camera.photometric_model): its response (gamma, black_level, shoulder, white_level, shoulder_order, "
        "curvature, the free tone curve tone_1..tone_6), through which the grey levels were mapped to the "
        "power law response_gamma where it goes beyond one, "
        "the level its sensor or tone curve clips at (clip_level, fraction of full scale; 1: none), at which "
        "the door's bright side and arris strips are refused overexposed, "
        "and the edges' shift by the point spread's asymmetry (edge_shift_u_px, edge_shift_v_px, image px), "
        "taken off every edge, and what the model leaves unexplained on the camera's real edges (residual_edge_px, "
        "px), counted in every edge's doubt; null: none (the power law alone, no shift)",
    )


class LineQuality(BaseModel):
    """Fit figures for one detected edge line."""

    model_config = ConfigDict(extra="allow")

    name: str = Field(description="which edge: 'bottom' (X-line), 'reference' (Z-line) or 'far' (thickness)")
    n_points: int = Field(description="edge points sampled along the line")
    n_inliers: int = Field(description="edge points kept by the robust fit")
    rms_residual_px: float | None = Field(None, description="RMS distance of the inliers to the line, px")
    rms_residual_mm: float | None = Field(None, description="the same on the hinge-face plane, mm")
    contrast: float | None = Field(None, description="median grey-level step across the edge, 0-255 scale")


class LocateResult(BaseModel):
    """What `doorloc locate` prints and `POST /v1/locate` returns (before targets are added).

    Pose fields are in the cell frame (mm, degrees); null when ``ok`` is false, and ``error`` then says why.
    """

    model_config = ConfigDict(extra="allow")

    image: str = Field(description="image name or path as given")
    ok: bool = Field(
        description="true: the door was located and the pose fields hold its pose; false: refused"
    )
    x_mm: float | None = Field(None, description="shift of the reference corner along cell +X, mm")
    z_mm: float | None = Field(None, description="shift of the reference corner along cell +Z, mm")
    yaw_deg: float | None = Field(None, description="door rotation in the hinge-face plane, degrees")
    thickness_mm: float | None = Field(None, description="measured door thickness, mm")
    thickness_verified: bool | None = Field(
        None,
        description="true: the measured thickness was checked against the door's within the tolerance; false: "
        "the image could not verify it (answered only under locate.thickness_check: report, the reason in "
        "thickness_unverified_reason); null when refused",
    )
    thickness_unverified_reason: str | None = Field(
        None, description="why the thickness could not be verified, a sentence; null when it was"
    )
    scale_mm_per_px: float | None = Field(
        None, description="dynamic scaling factor at the corner, mm per pixel"
    )
    corner_px: list[float] | None = Field(None, description="reference corner in the image, [u, v] px")
    error: str | None = Field(None, description="null, or a sentence a person can act on")
    error_code: str | None = Field(
        None, description="machine-readable refusal reason, e.g. 'no_door', 'outside_envelope'"
    )
    uncertainty: PoseUncertainty | None = Field(
        None, description="1-sigma standard uncertainty of the pose (null when ok is false)"
    )
    provenance: Provenance | None = Field(
        None, description="software version and the hashes of the model used"
    )
    model: PhysicalModel | None = Field(
        None, description="the physical settings locate assumed (response, arris, lighting side)"
    )
    elapsed_ms: float = Field(0.0, description="time spent in locate, ms (decode excluded)")
    lines: list[LineQuality] = Field(default_factory=list, description="per-line fit figures")
    diagnostics: dict[str, Any] = Field(default_factory=dict, description="anything else worth knowing")

    @classmethod
    def refusal(
        cls, image: str, error_code: str, error: str, elapsed_ms: float = 0.0, **extra: Any
    ) -> LocateResult:
        """A refusal: ``ok=false``, pose fields null, a reason a person can act on."""
        return cls(image=image, ok=False, error=error, error_code=error_code, elapsed_ms=elapsed_ms, **extra)

    def refused(self, error_code: str, error: str) -> LocateResult:
        """This answer refused with ``error_code`` and ``error`` (another reading of the door judged it), its
        lines and diagnostics kept and its pose as ``diagnostics.measured``."""
        measured = {k: getattr(self, k) for k in ("x_mm", "z_mm", "yaw_deg", "thickness_mm")}
        return LocateResult.refusal(
            self.image,
            error_code,
            error,
            lines=self.lines,
            diagnostics=self.diagnostics | {"measured": measured},
        )
