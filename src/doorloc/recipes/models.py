"""Door recipes: the thesis's "feature and door data" as validated pydantic values (SPEC section 6).

A :class:`DoorRecipe` is what the planner needs to mill one door's hinge pockets: the door's nominal
size, its hinges (pocket rectangles on the hinge-edge face, door frame), the tool and its feed.
Field-level rules (positive sizes, path kind) are pydantic constraints; rules that relate fields
(a hinge inside the door, hinges not overlapping, the tool fitting the corner radius...) are listed
by :func:`recipe_problems`, each naming the field and the reason, so an importer can map them to
rows and columns. Building a ``DoorRecipe`` runs both and raises :class:`pydantic.ValidationError`.

Door frame (doorloc.pose): X across the thickness from the reference face (``[0, T]``), Y into the
door from the hinge-edge face (``[0, W]``), Z up from the bottom end (``[0, H]``); millimetres.

Examples
--------
>>> r = DoorRecipe(door_id="D-1", width_mm=900, height_mm=2100, thickness_mm=50,
...                hinges=[Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3,
...                              corner_radius_mm=8)],
...                tool_diameter_mm=16, spindle_rpm=18000, feed_mm_s=25)
>>> r.door_size().thickness_mm
50.0
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from doorloc.domain import DoorSize
from doorloc.limits import (
    DEFAULT_MILLING_LIMITS,
    DOOR_RANGES_MM,
    TOOL_DIAMETER_RANGE_MM,
    DoorRangeError,
    MillingLimits,
    check_range,
)

__all__ = [
    "PointCorrection",
    "Hinge",
    "DoorFields",
    "DoorRecipe",
    "SKIP_CROSS_CHECKS",
    "MILLING",
    "CORNER_OVERCUT_TOLERANCE_MM",
    "RecipeProblem",
    "recipe_problems",
    "milling_problems",
    "DOOR_ID_PATTERN",
]

#: door ids are barcodes: letters, digits and ``-_./:`` (no separators the text exports use)
DOOR_ID_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.:/-]{0,63}$"

PositiveMm = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeMm = Annotated[float, Field(ge=0, allow_inf_nan=False)]
CorrectionMm = Annotated[float, Field(ge=-5.0, le=5.0, allow_inf_nan=False)]

#: milled-feature tolerance (thesis, SPEC section 7): the most a 6-point path may cut past a corner arc, mm
CORNER_OVERCUT_TOLERANCE_MM = 0.5

#: context flag for ``model_validate``: build the recipe without the cross-field checks
#: (an importer then calls :func:`recipe_problems` itself to map each problem to a row and column)
SKIP_CROSS_CHECKS = "skip_cross_checks"

#: context key for ``model_validate``: the :class:`~doorloc.limits.MillingLimits` (spindle speed, feed, tool
#: reach) to check against, the cell's; None leaves those bounds to be checked where the recipe meets a cell
#: (:func:`milling_problems`), as a recipe read back from the database is. Without it: doorloc's defaults
MILLING = "milling"


def _milling_of(info: ValidationInfo) -> MillingLimits | None:
    ctx = info.context
    if isinstance(ctx, dict) and MILLING in ctx:
        limits: MillingLimits | None = ctx[MILLING]
        return limits
    return DEFAULT_MILLING_LIMITS


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class PointCorrection(_Frozen):
    """Force-displacement correction of one pocket path point, door frame, mm (thesis's PC term, eq. 3.46).

    The milling force bends the robot by a predictable amount (thesis section 3.8, eq. 3.44-3.45);
    these values are the compensation, added as given to the point before the pose moves it into
    the cell.
    """

    dx_mm: CorrectionMm = 0.0
    dy_mm: CorrectionMm = 0.0
    dz_mm: CorrectionMm = 0.0


class Hinge(_Frozen):
    """One hinge pocket on the hinge-edge face, door frame, mm.

    The pocket is the rectangle ``x_mm <= X <= x_mm + width_mm``, ``z_mm <= Z <= z_mm + length_mm``
    with corners rounded by ``corner_radius_mm``, milled ``depth_mm`` deep into the face (+Y).
    ``path_points`` picks the tool path (doorloc.recipes.paths): 6 (simple fillet, the tool's own
    radius rounds the corners) or 9 (thesis figure 3.24a: two points per corner arc).
    ``corrections`` is empty or holds one :class:`PointCorrection` per pocket point P1..Pn.
    """

    z_mm: NonNegativeMm
    length_mm: PositiveMm
    width_mm: PositiveMm
    x_mm: NonNegativeMm
    depth_mm: PositiveMm
    corner_radius_mm: NonNegativeMm
    path_points: Literal[6, 9] = 6
    corrections: tuple[PointCorrection, ...] = ()

    @field_validator("corrections")
    @classmethod
    def _one_per_point(
        cls, v: tuple[PointCorrection, ...], info: ValidationInfo
    ) -> tuple[PointCorrection, ...]:
        if "path_points" not in info.data:  # the path kind itself was bad: that error is reported already
            return v
        n = info.data["path_points"]
        if v and len(v) != n:
            raise ValueError(
                f"give one correction per pocket point (P1..P{n}: {n} values) or none, got {len(v)}"
            )
        return v


class DoorFields(_Frozen):
    """The door-level fields of a recipe (everything but the hinges); see :class:`DoorRecipe`."""

    door_id: str = Field(pattern=DOOR_ID_PATTERN)
    width_mm: PositiveMm
    height_mm: PositiveMm
    thickness_mm: PositiveMm
    arris_mm: NonNegativeMm = 0.0
    tool_diameter_mm: PositiveMm
    spindle_rpm: Annotated[float, Field(gt=0, le=100_000, allow_inf_nan=False)]
    feed_mm_s: Annotated[float, Field(gt=0, le=5_000, allow_inf_nan=False)]

    @field_validator("width_mm", "height_mm", "thickness_mm", "tool_diameter_mm", "spindle_rpm", "feed_mm_s")
    @classmethod
    def _in_range(cls, v: float, info: ValidationInfo) -> float:
        # the accepted ranges live in doorloc.limits (shared with the HTTP API and the CLI); the spindle's
        # speed and the feed are the cell's (validation context MILLING)
        name = info.field_name or ""
        if name in ("spindle_rpm", "feed_mm_s"):
            milling = _milling_of(info)
            if milling is None:
                return v
            return check_range(name, v, getattr(milling, name), milling)
        return check_range(
            name, v, TOOL_DIAMETER_RANGE_MM if name == "tool_diameter_mm" else DOOR_RANGES_MM[name]
        )


class DoorRecipe(DoorFields):
    """Everything needed to mill one door's hinge pockets (SPEC section 6).

    Attributes
    ----------
    door_id : str
        The door's barcode (letters, digits, ``-_./:``; at most 64 characters).
    width_mm, height_mm, thickness_mm : float
        Nominal door size, mm (Y, Z and X extents in the door frame).
    arris_mm : float
        Size of the rounding/chamfer on the hinge-face edges, mm (0: sharp).
    tool_diameter_mm : float
        Diameter of the end mill, mm.
    spindle_rpm : float
        Spindle speed, revolutions per minute.
    feed_mm_s : float
        Milling feed rate along the path, mm/s (the RAPID module's speeddata v_tcp).
    hinges : tuple of Hinge
        The hinge pockets (1 to 20), numbered 1.. in the order given.
    """

    hinges: tuple[Hinge, ...] = Field(min_length=1, max_length=20)

    @model_validator(mode="after")
    def _cross_checks(self, info: ValidationInfo) -> DoorRecipe:
        if info.context and info.context.get(SKIP_CROSS_CHECKS):
            return self
        problems = recipe_problems(self, _milling_of(info))
        if problems:
            raise ValueError("; ".join(f"{p.field}: {p.message}" for p in problems))
        return self

    def door_size(self) -> DoorSize:
        """The door's nominal size as the cell and the vision code use it."""
        return DoorSize(self.width_mm, self.thickness_mm, self.height_mm, self.arris_mm)


@dataclass(frozen=True)
class RecipeProblem:
    """One violated rule: ``field`` as a path into the recipe (``hinges[1].x_mm``), ``hinge`` its index."""

    field: str
    message: str
    hinge: int | None = None


def _g(v: float) -> str:
    return f"{v:g}"


def _too_deep(r: DoorRecipe, i: int, milling: MillingLimits) -> RecipeProblem:
    depth = r.hinges[i].depth_mm
    return RecipeProblem(
        f"hinges[{i}].depth_mm",
        f"hinge {i + 1} pocket depth {_g(depth)} mm is deeper than the hinge cutter reaches "
        f"(tool_reach_mm {_g(milling.tool_reach_mm)} mm: {milling.origin('tool_reach_mm')}); a hinge leaf "
        "needs 2-5 mm",
        i,
    )


def milling_problems(r: DoorRecipe, milling: MillingLimits) -> list[RecipeProblem]:
    """Every bound of the cell's spindle and cutter the recipe breaks: its spindle speed and feed outside their
    ranges, a pocket deeper than the tool reaches. Each sentence names the bound and where it came from (the
    cell file's ``milling:`` key, or doorloc's default)."""
    out: list[RecipeProblem] = []
    for name in ("spindle_rpm", "feed_mm_s"):
        try:
            check_range(name, getattr(r, name), getattr(milling, name), milling)
        except DoorRangeError as e:
            out.append(RecipeProblem(name, str(e)))
    out += [
        _too_deep(r, i, milling)
        for i, h in enumerate(r.hinges)
        if milling.tool_reach_mm < h.depth_mm < min(r.thickness_mm, r.width_mm)
    ]
    return out


def recipe_problems(
    r: DoorRecipe, milling: MillingLimits | None = DEFAULT_MILLING_LIMITS
) -> list[RecipeProblem]:
    """Every cross-field rule the recipe breaks (empty when it is millable).

    Rules: the arris is less than half the thickness; each pocket lies inside the door
    (``x + width <= thickness``, ``z + length <= height``, ``depth < width`` of the door), and is shallower
    than the door is thick and no deeper than the cutter reaches (``milling.tool_reach_mm``, the cell's; None:
    left to :func:`milling_problems` where the recipe meets a cell); the corner
    radius fits the pocket; the tool fits the corner radius (``tool_diameter <= 2 * corner_radius``),
    a 6-point path cuts no more than :data:`CORNER_OVERCUT_TOLERANCE_MM` past the corner arcs
    (``(corner_radius - tool_radius) * (sqrt 2 - 1)``), and the contour clears the whole pocket
    (``min(width, length) <= 2 * tool_diameter``);
    no two pockets overlap.
    """
    out: list[RecipeProblem] = []
    if r.arris_mm >= r.thickness_mm / 2:
        out.append(
            RecipeProblem(
                "arris_mm",
                f"arris {_g(r.arris_mm)} mm must be less than half the "
                f"thickness ({_g(r.thickness_mm / 2)} mm)",
            )
        )
    d = r.tool_diameter_mm
    for i, h in enumerate(r.hinges):
        name = f"hinges[{i}]"
        n = i + 1
        if h.x_mm + h.width_mm > r.thickness_mm + 1e-9:
            out.append(
                RecipeProblem(
                    f"{name}.width_mm",
                    f"hinge {n} pocket spans X {_g(h.x_mm)}..{_g(h.x_mm + h.width_mm)} mm, "
                    f"wider than the door thickness {_g(r.thickness_mm)} mm "
                    f"(x_mm + width_mm must be <= thickness)",
                    i,
                )
            )
        if h.z_mm + h.length_mm > r.height_mm + 1e-9:
            out.append(
                RecipeProblem(
                    f"{name}.length_mm",
                    f"hinge {n} pocket ends at Z {_g(h.z_mm + h.length_mm)} mm, "
                    f"above the door top {_g(r.height_mm)} mm",
                    i,
                )
            )
        if h.depth_mm >= r.width_mm:
            out.append(
                RecipeProblem(
                    f"{name}.depth_mm",
                    f"hinge {n} pocket depth {_g(h.depth_mm)} mm must be less "
                    f"than the door width {_g(r.width_mm)} mm",
                    i,
                )
            )
        elif h.depth_mm >= r.thickness_mm:
            out.append(
                RecipeProblem(
                    f"{name}.depth_mm",
                    f"hinge {n} pocket depth {_g(h.depth_mm)} mm must be less than the door thickness "
                    f"{_g(r.thickness_mm)} mm; a hinge leaf needs 2-5 mm",
                    i,
                )
            )
        elif milling is not None and h.depth_mm > milling.tool_reach_mm:
            out.append(_too_deep(r, i, milling))
        if h.corner_radius_mm > min(h.width_mm, h.length_mm) / 2 + 1e-9:
            out.append(
                RecipeProblem(
                    f"{name}.corner_radius_mm",
                    f"hinge {n} corner radius {_g(h.corner_radius_mm)} mm "
                    f"exceeds half the pocket's width/length "
                    f"({_g(min(h.width_mm, h.length_mm) / 2)} mm)",
                    i,
                )
            )
        if d > 2 * h.corner_radius_mm + 1e-9:
            out.append(
                RecipeProblem(
                    "tool_diameter_mm",
                    f"tool diameter {_g(d)} mm does not fit hinge {n}'s corner "
                    f"radius {_g(h.corner_radius_mm)} mm (needs diameter <= "
                    f"2 * radius = {_g(2 * h.corner_radius_mm)} mm)",
                    i,
                )
            )
        overcut = (h.corner_radius_mm - d / 2) * (2**0.5 - 1)
        if (
            h.path_points == 6
            and d <= 2 * h.corner_radius_mm + 1e-9
            and overcut > CORNER_OVERCUT_TOLERANCE_MM
        ):
            out.append(
                RecipeProblem(
                    f"{name}.path_points",
                    f"hinge {n}: the 6-point path cuts its corners with the "
                    f"tool radius {_g(d / 2)} mm, {overcut:.2f} mm past the "
                    f"{_g(h.corner_radius_mm)} mm corner radius (limit "
                    f"{_g(CORNER_OVERCUT_TOLERANCE_MM)} mm): use the 9-point "
                    f"path or a tool closer to 2 * corner radius",
                    i,
                )
            )
        if min(h.width_mm, h.length_mm) > 2 * d + 1e-9:
            out.append(
                RecipeProblem(
                    f"{name}.width_mm",
                    f"hinge {n} pocket ({_g(h.width_mm)} x {_g(h.length_mm)} mm) "
                    f"is more than two tool diameters ({_g(2 * d)} mm) wide: "
                    f"the contour path would leave an uncut island",
                    i,
                )
            )
    order = sorted(range(len(r.hinges)), key=lambda k: r.hinges[k].z_mm)
    for a_pos, a in enumerate(order):
        ha = r.hinges[a]
        for b in order[a_pos + 1 :]:
            hb = r.hinges[b]
            if hb.z_mm >= ha.z_mm + ha.length_mm:
                break
            if hb.x_mm < ha.x_mm + ha.width_mm and ha.x_mm < hb.x_mm + hb.width_mm:
                out.append(
                    RecipeProblem(
                        f"hinges[{b}].z_mm",
                        f"hinge {b + 1} (Z {_g(hb.z_mm)}..{_g(hb.z_mm + hb.length_mm)} mm) "
                        f"overlaps hinge {a + 1} (Z {_g(ha.z_mm)}.."
                        f"{_g(ha.z_mm + ha.length_mm)} mm)",
                        b,
                    )
                )
    return out
