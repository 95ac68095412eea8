"""A model check's verdict and action in plain words, and each cause's physical meaning.

What a plant engineer reads first (``report.md``'s head, the console, ``report.json``'s ``verdict``): is the
cell right, what is wrong with it, is the extended cell safe to use, and what to do.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from doorloc.modelcheck.check import ModelCheckReport

__all__ = ["Verdict", "verdict_of", "meaning", "LEVER_EXPLAINED", "MIN_VERIFIED_GAIN"]

Status = Literal["fits", "extend", "recalibrate", "not_verified", "unexplained"]

#: Below this held-out gain the extended cell is not worth offering (its change is within the noise)
MIN_VERIFIED_GAIN = 1.5

LEVER_EXPLAINED = (
    "the error of a point 1 m up the door's hinge edge: the corner's x and z error combined with the yaw "
    "error times 1000 mm (what a hinge pocket 1 m up would be off by)"
)


@dataclass(frozen=True)
class Verdict:
    """``status``: fits (nothing to change), extend (use the extended cell), recalibrate (the data name a
    value no calibration allows), not_verified (the extended cell failed on the held-out images),
    unexplained (structure no catalogue effect explains). ``headline`` and ``action``: plain sentences."""

    status: Status
    headline: str
    action: str

    def to_dict(self) -> dict[str, str]:
        return asdict(self)


def _v(values: Mapping[str, float], key: str) -> float:
    return float(values.get(key, float("nan")))


def meaning(cause: str, values: Mapping[str, float], variant: str = "") -> str:
    """What ``cause`` at the fitted offsets ``values`` (parameter name -> value) means physically."""
    if cause == "camera_roll":
        return f"the camera is turned {_v(values, 'roll_deg'):+.3f} deg about its optical axis"
    if cause == "camera_tilt":
        return (
            f"the camera is tilted {_v(values, 'tilt_deg'):+.3f} deg (image rows move) and panned "
            f"{_v(values, 'pan_deg'):+.3f} deg (columns move), or its principal point is off by as much"
        )
    if cause == "camera_distance":
        d = _v(values, "distance_mm")
        return f"the camera is {abs(d):.2f} mm {'farther from' if d > 0 else 'nearer to'} the door than the cell says"
    if cause == "lateral_offset":
        return (
            f"the camera centre has moved {_v(values, 'dx_mm'):+.3f} mm along the cell's X and "
            f"{_v(values, 'dz_mm'):+.3f} mm along Z"
        )
    if cause == "focal_length":
        return f"the focal length is {_v(values, 'focal_pct'):+.3f} % off the calibration's (zoom or focus moved)"
    if cause == "pixel_aspect":
        return f"the pixels' height/width ratio (fy/fx) is {_v(values, 'aspect_pct'):+.3f} % off the calibration's"
    if cause == "radial_distortion":
        return f"the lens bends straight lines (radial distortion k1 {_v(values, 'k1'):+.4f}) more than the cell says"
    if cause == "arris":
        return (
            f"the doors' edges are {'rounded' if variant == 'round' else 'chamfered'} by "
            f"{_v(values, 'arris_mm'):.2f} mm more than the cell assumes"
        )
    if cause == "fixture_depth":
        return (
            f"the fixture holds the door's face {_v(values, 'face_shift_per_width'):+.4f} mm deeper per mm of "
            "door width than the cell says"
        )
    if cause == "response_gamma":
        return f"the camera's grey levels follow a response exponent of {_v(values, 'response_gamma'):.2f}"
    return cause


def _values(rep: ModelCheckReport, cause: str) -> dict[str, float]:
    return {p: v["value"] for p, v in rep.parameters.get(cause, {}).items()}


def _offsets(rep: ModelCheckReport, cause: str) -> dict[str, float]:
    """Fitted offsets from the cell (``response_gamma`` is an absolute exponent and stays one)."""
    return _values(rep, cause)


def verdict_of(rep: ModelCheckReport) -> Verdict:
    """The verdict and action for ``rep`` (see :class:`Verdict`)."""
    named = [c for c in rep.causes if c != "unexplained"]
    before = rep.heldout_rms_before.get("lever_mm", float("nan"))
    after = rep.heldout_rms_after.get("lever_mm", float("nan"))
    n_held = len(rep.heldout_images)
    if not named:
        if "unexplained" in rep.causes:
            return Verdict(
                "unexplained",
                f"The cell is off in a way none of the {len(rep.considered) or 10} known causes explains "
                f"(held-out error 1 m up the door {before:.3f} mm).",
                "Keep using the cell only if that error is acceptable; look for a cause outside the catalogue "
                "(a decentred lens, a fixture that moves, a reference gauge that is off) in residuals.png, "
                "then check again. No extended cell is offered.",
            )
        return Verdict(
            "fits",
            f"The cell is right: its poses on these {len(rep.train_images) + n_held} images are off only "
            f"by their noise (held-out error 1 m up the door {before:.3f} mm).",
            "Nothing to change; keep using the cell.",
        )
    what = "; ".join(
        meaning(c, _offsets(rep, c), rep.plausibility.get(c, {}).get("variant", "")) for c in named
    )
    if rep.heldout_refused_after:
        why = "; ".join(rep.heldout_refusal_reasons[:2]) or "refused"
        return Verdict(
            "not_verified",
            f"The data point to: {what}. But locate with the extended cell refused "
            f"{len(rep.heldout_refused_after)} of {n_held} held-out images ({why}).",
            "Do not use cell_extended.yaml; keep the given cell and check the door or camera this names by "
            "hand.",
        )
    if not after < before / MIN_VERIFIED_GAIN:
        return Verdict(
            "not_verified",
            f"The data point to: {what}. But the extended cell did not make the held-out images better "
            f"({before:.4f} -> {after:.4f} mm 1 m up the door).",
            "Do not use cell_extended.yaml; keep the given cell.",
        )
    implausible = [c for c in named if rep.plausibility.get(c, {}).get("implausible")]
    gain = f"held-out error 1 m up the door {before:.3f} -> {after:.3f} mm, {rep.heldout_gain:.1f}x better"
    left = " Some structure is left that no known cause explains." if "unexplained" in rep.causes else ""
    if implausible:
        far = ", ".join(
            f"{c} is {rep.plausibility[c]['sigmas_from_cell']:.0f} sigma from the cell's value "
            f"({rep.plausibility[c]['prior_source']})"
            for c in implausible
        )
        return Verdict(
            "recalibrate",
            f"The cell is wrong: {what} ({gain}). That is far more than the cell's own uncertainty allows "
            f"({far}).{left}",
            "Re-measure what this names (recalibrate the camera with `doorloc calibrate`, or check the mount) "
            "and check again; cell_extended.yaml corrects these images but is flagged implausible: use it "
            "only until then.",
        )
    return Verdict(
        "extend",
        f"The cell is wrong: {what} ({gain}).{left}",
        "Use cell_extended.yaml in place of the cell (locate, batch and serve read it with --cell); keep "
        "the old file to compare.",
    )
