"""The door sizes doorloc accepts, in one place: the HTTP API, recipe import (CSV/XLSX) and the CLI use these.

SPEC section 7 (the thesis's cell) handles doors 30-100 mm thick, 190-1350 mm wide and 1000-3000 mm high.
Accepted ranges add a margin on both sides, so a door slightly outside the thesis's catalogue is still
measured, while a typo (``width_mm=1e308``, ``thickness_mm=10000``) is refused with a sentence naming the
field instead of reaching the vision code, where it would end as ``internal_error``.

Examples
--------
>>> door_size_problems(900, 50, 2100, 0)
[]
>>> door_size_problems(1e308, 50, 2100, 0)[0][0]
'width_mm'
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = [
    "MillingLimits",
    "DEFAULT_MILLING_LIMITS",
    "DOOR_RANGES_MM",
    "SPEC_RANGES_MM",
    "TOOL_DIAMETER_RANGE_MM",
    "SPINDLE_RPM_RANGE",
    "FEED_RANGE_MM_S",
    "TOOL_REACH_MM",
    "check_range",
    "door_size_problems",
    "range_sentence",
    "DoorRangeError",
]

#: SPEC section 7 (thesis): the doors the cell was built for, mm
SPEC_RANGES_MM: dict[str, tuple[float, float]] = {
    "thickness_mm": (30.0, 100.0),
    "width_mm": (190.0, 1350.0),
    "height_mm": (1000.0, 3000.0),
}
#: accepted: SPEC's ranges with margins (about a third of the lower bound below, ~10-20 % above), mm
DOOR_RANGES_MM: dict[str, tuple[float, float]] = {
    "thickness_mm": (20.0, 120.0),
    "width_mm": (150.0, 1500.0),
    "height_mm": (800.0, 3300.0),
}
#: end mills for hinge pockets: 3-50 mm
TOOL_DIAMETER_RANGE_MM = (3.0, 50.0)
#: the spindle's speed range, rev/min: a woodworking electro-spindle runs ~1,000-24,000 (some 30,000); the
#: thesis's recipes use 3,200 and 18,000. 100,000 is a typo, not a setting
SPINDLE_RPM_RANGE = (1000.0, 30000.0)
#: milling feed along the path, mm/s: up to 30 m/min in wood; 5,000 mm/s is a typo
FEED_RANGE_MM_S = (0.1, 500.0)
#: deepest pocket the hinge cutter reaches, mm: the cutting length of a hinge-mortise end mill (hinge leaves
#: are 2-5 mm thick). A pocket is also shallower than the door is thick
TOOL_REACH_MM = 25.0


@dataclass(frozen=True)
class MillingLimits:
    """What the cell's spindle and hinge cutter can do: the bounds a recipe's speed, feed and depth must keep.

    A cell file states them in its ``milling:`` section (shared/SPEC.md section 2); each bound it leaves out is
    doorloc's default (:data:`SPINDLE_RPM_RANGE`, :data:`FEED_RANGE_MM_S`, :data:`TOOL_REACH_MM`).

    Attributes
    ----------
    spindle_rpm : (float, float)
        The spindle's speed range, rev/min.
    feed_mm_s : (float, float)
        The milling feeds the cell runs, mm/s along the path.
    tool_reach_mm : float
        The deepest pocket the hinge cutter mills, mm (its cutting length).
    source : str or None
        The cell file that stated them (None: no cell file).
    stated : frozenset of str
        The bounds (``spindle_rpm``, ``feed_mm_s``, ``tool_reach_mm``) that file states; the others are defaults.
    """

    spindle_rpm: tuple[float, float] = SPINDLE_RPM_RANGE
    feed_mm_s: tuple[float, float] = FEED_RANGE_MM_S
    tool_reach_mm: float = TOOL_REACH_MM
    source: str | None = None
    stated: frozenset[str] = field(default_factory=frozenset)

    def origin(self, bound: str) -> str:
        """Where ``bound`` came from, for a refusal: ``"milling.spindle_rpm in cell.yaml"`` or the default."""
        if bound in self.stated:
            return f"milling.{bound} in {self.source or 'the cell file'}"
        return f"doorloc's default; a cell file sets it as milling.{bound}"


#: the bounds of a cell whose file states none
DEFAULT_MILLING_LIMITS = MillingLimits()

_WORDS = {
    "thickness_mm": "door thickness",
    "width_mm": "door width",
    "height_mm": "door height",
    "tool_diameter_mm": "tool diameter",
    "spindle_rpm": "spindle speed",
    "feed_mm_s": "feed rate",
}
#: units of the non-length fields in the sentences
_UNITS = {"spindle_rpm": "rev/min", "feed_mm_s": "mm/s"}


class DoorRangeError(ValueError):
    """A door size outside the accepted range; ``field`` names it (e.g. ``width_mm``)."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


def range_sentence(
    field: str, value: float, lo: float, hi: float, milling: MillingLimits | None = None
) -> str:
    """``"door width (width_mm) 1e+308 mm is outside the accepted 150-1500 mm ..."``: what is wrong and what is
    accepted (for the spindle speed and the feed, which bound it is and where it came from: ``milling``)."""
    what = _WORDS.get(field, field)
    spec = SPEC_RANGES_MM.get(field)
    note = f" (the cell is built for {spec[0]:g}-{spec[1]:g} mm)" if spec else ""
    if field in ("spindle_rpm", "feed_mm_s"):
        whose = "the spindle's range" if field == "spindle_rpm" else "the cell's milling feeds"
        note = f" ({whose}: {(milling or DEFAULT_MILLING_LIMITS).origin(field)})"
    unit = _UNITS.get(field, "mm")
    return f"{what} ({field}) {value:g} {unit} is outside the accepted {lo:g}-{hi:g} {unit}{note}"


def check_range(
    field: str,
    value: float,
    bounds: tuple[float, float] | None = None,
    milling: MillingLimits | None = None,
) -> float:
    """``value`` when it is a finite number inside the field's range, else DoorRangeError naming the field
    (``milling``: where the spindle speed's and feed's ranges came from, for the sentence)."""
    lo, hi = bounds or DOOR_RANGES_MM[field]
    v = float(value)
    if not math.isfinite(v):
        raise DoorRangeError(
            field,
            f"{_WORDS.get(field, field)} ({field}) must be a finite number of millimetres, got {value!r}",
        )
    if not lo <= v <= hi:
        raise DoorRangeError(field, range_sentence(field, v, lo, hi, milling))
    return v


def door_size_problems(
    width_mm: float, thickness_mm: float, height_mm: float, arris_mm: float = 0.0
) -> list[tuple[str, str]]:
    """Every ``(field, sentence)`` the door size breaks: ranges, and the arris below half the thickness."""
    out = []
    for name, v in (("width_mm", width_mm), ("thickness_mm", thickness_mm), ("height_mm", height_mm)):
        try:
            check_range(name, v)
        except DoorRangeError as e:
            out.append((name, str(e)))
    if not (math.isfinite(arris_mm) and 0 <= arris_mm < thickness_mm / 2):
        out.append(
            (
                "arris_mm",
                f"arris (arris_mm) {arris_mm:g} mm must be at least 0 and less than half the "
                f"door thickness ({thickness_mm / 2:g} mm)",
            )
        )
    return out
