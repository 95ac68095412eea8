"""The cell file's ``robot:`` section: which robot, where its base stands, its tool, and the RAPID data.

One strict model (unknown keys are errors) holds both the SPEC keys (shared/SPEC.md sections 2 and 9)
and the keys the RAPID module needs (docs/hinge_paths.md)::

    robot:
      model: irb6600-175-2.55            # a bundled robot or a robot file (.yaml); none: no reach check
      base: {pos_mm: [x, y, z], quat: [w, x, y, z]}   # robot base frame in the cell frame
      tool: {pos_mm: [x, y, z], quat: [w, x, y, z]}   # flange (tool0) to TCP = RAPID tframe
      tool_name: tSpindle                 # RAPID keys, all optional
      spindle_axis: y
      ...

The same facts are never given twice in two ways: ``tool`` *is* RAPID's ``tframe`` (the older keys
``tool_tcp_mm``/``tool_rot`` are accepted as its spelling when ``tool`` is absent), and ``base``
fixes RAPID's work object: the cell frame seen from the robot's world frame (taken as the base frame),
``wobj_uframe = base^-1``. Giving ``base`` and ``wobj_uframe_*`` that disagree is an error.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from scipy.spatial.transform import Rotation

from doorloc.domain import tool_base_orientation

__all__ = ["Placement", "RobotSection", "robot_section_from_doc", "RobotSectionError"]

Quat = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]
_IDENT = r"^[A-Za-z][A-Za-z0-9_]{0,31}$"
Num = Annotated[float, Field(allow_inf_nan=False)]


class RobotSectionError(ValueError):
    """A ``robot:`` section that cannot be used; the message names the key."""


def _unit_quat(q: tuple[float, ...]) -> Quat:
    n = math.sqrt(math.fsum(v * v for v in q))
    if not math.isfinite(n) or abs(n - 1.0) > 1e-3:
        raise ValueError(
            f"quat must be a unit quaternion [w, x, y, z] (norm 1 within 1e-3), got norm {n:.6g}"
        )
    w, x, y, z = (v / n for v in q)
    return (w, x, y, z) if w >= 0 else (-w, -x, -y, -z)


class Placement(BaseModel):
    """A rigid transform: position (mm) and orientation (unit quaternion, scalar first ``[w, x, y, z]``)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    pos_mm: tuple[Num, Num, Num] = (0.0, 0.0, 0.0)
    quat: tuple[Num, Num, Num, Num] = (1.0, 0.0, 0.0, 0.0)

    @field_validator("quat")
    @classmethod
    def _unit(cls, v: tuple[float, float, float, float]) -> Quat:
        return _unit_quat(v)

    def matrix(self) -> np.ndarray:
        """4x4 homogeneous transform, mm."""
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat(self.quat, scalar_first=True).as_matrix()
        T[:3, 3] = self.pos_mm
        return T

    def inverse(self) -> Placement:
        """The inverse transform."""
        r = Rotation.from_quat(self.quat, scalar_first=True).inv()
        x, y, z = (float(v) for v in -r.apply(np.asarray(self.pos_mm, dtype=float)))
        qw, qx, qy, qz = (float(v) for v in r.as_quat(scalar_first=True))
        return Placement(pos_mm=(x, y, z), quat=(qw, qx, qy, qz))

    def close_to(self, other: Placement, tol_mm: float = 1e-3, tol_deg: float = 1e-4) -> bool:
        """Same transform within ``tol_mm`` and ``tol_deg``."""
        dp = float(np.linalg.norm(np.subtract(self.pos_mm, other.pos_mm)))
        r = Rotation.from_quat(self.quat, scalar_first=True).inv() * Rotation.from_quat(
            other.quat, scalar_first=True
        )
        return dp <= tol_mm and math.degrees(r.magnitude()) <= tol_deg


class RobotSection(BaseModel):
    """The cell file's ``robot:`` section (all keys optional).

    Attributes
    ----------
    model : str or None
        Robot model name (``irb6600-175-2.55``) or a robot file path (relative to the cell file);
        None: the cell names no robot and nothing checks reach.
    base : Placement
        The robot base frame in the cell frame (``p_cell = R p_base + pos``). Default: the inverse of
        ``wobj_uframe_*`` (identity: base frame = cell frame).
    tool : Placement
        Flange (ABB ``tool0``) to TCP: where the tool frame lies in the flange frame. The tool frame's
        spindle axis is its +Y (``spindle_axis: y``) or +Z. Default: from ``tool_tcp_mm``/``tool_rot``.
    tool_name, spindle_axis, tool_tcp_mm, tool_rot, tool_mass_kg, tool_cog_mm, wobj_name, wobj_uframe_mm,
    wobj_uframe_rot, robconf, travel_speed, travel_zone
        RAPID data (docs/hinge_paths.md). After validation ``tool_tcp_mm``/``tool_rot`` equal ``tool``
        and ``wobj_uframe_*`` equal ``base``'s inverse.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    model: str | None = None
    base: Placement | None = None
    tool: Placement | None = None
    tool_name: str = Field(default="tSpindle", pattern=_IDENT)
    spindle_axis: Literal["y", "z"] = "y"
    tool_tcp_mm: tuple[Num, Num, Num] = (0.0, 0.0, 250.0)
    tool_rot: tuple[Num, Num, Num, Num] | None = None
    tool_mass_kg: float = Field(default=12.0, gt=0)
    tool_cog_mm: tuple[Num, Num, Num] = (0.0, 0.0, 120.0)
    wobj_name: str = Field(default="wobjDoorCell", pattern=_IDENT)
    wobj_uframe_mm: tuple[Num, Num, Num] = (0.0, 0.0, 0.0)
    wobj_uframe_rot: tuple[Num, Num, Num, Num] = (1.0, 0.0, 0.0, 0.0)
    robconf: tuple[int, int, int, int] = (0, 0, 0, 0)
    travel_speed: str = Field(default="v200", pattern=_IDENT)
    travel_zone: str = Field(default="z5", pattern=_IDENT)

    @field_validator("tool_rot", "wobj_uframe_rot")
    @classmethod
    def _unit(cls, v: tuple[float, float, float, float] | None) -> Quat | None:
        return None if v is None else _unit_quat(v)

    @model_validator(mode="after")
    def _one_truth(self) -> RobotSection:
        given = self.model_fields_set
        # the tool: `tool` (SPEC) is RAPID's tframe; the older tool_tcp_mm/tool_rot spell the same thing
        if self.tool is not None and given & {"tool_tcp_mm", "tool_rot"}:
            raise ValueError(
                "give the tool once: 'tool' (pos_mm, quat) or the older 'tool_tcp_mm'/'tool_rot', not both"
            )
        if self.tool is None:
            rot = self.tool_rot
            if rot is None:
                rot = (
                    (math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0)
                    if self.spindle_axis == "y"
                    else (1.0, 0.0, 0.0, 0.0)
                )
            object.__setattr__(self, "tool_rot", rot)
            object.__setattr__(self, "tool", Placement(pos_mm=self.tool_tcp_mm, quat=rot))
        else:
            object.__setattr__(self, "tool_tcp_mm", self.tool.pos_mm)
            object.__setattr__(self, "tool_rot", self.tool.quat)
        # the base: the work object is the cell frame in the robot's world (= base) frame
        wobj = Placement(pos_mm=self.wobj_uframe_mm, quat=self.wobj_uframe_rot)
        if self.base is None:
            object.__setattr__(self, "base", wobj.inverse())
        else:
            inv = self.base.inverse()
            if given & {"wobj_uframe_mm", "wobj_uframe_rot"} and not inv.close_to(wobj):
                raise ValueError(
                    "'base' and 'wobj_uframe_mm'/'wobj_uframe_rot' disagree: the work object must be "
                    "the inverse of the base placement (give only 'base')"
                )
            object.__setattr__(self, "wobj_uframe_mm", inv.pos_mm)
            object.__setattr__(self, "wobj_uframe_rot", inv.quat)
        return self

    def base_orientation(self) -> Quat:
        """Tool orientation at yaw 0 for :func:`doorloc.recipes.targets.targets_for_pose`."""
        return tool_base_orientation(self.spindle_axis)

    def robot_path(self, cell_dir: str | Path | None = None) -> str | None:
        """``model`` as :func:`doorloc.robot.model.load_robot` takes it (a relative file resolved at the cell)."""
        if self.model is None:
            return None
        if re.search(r"\.ya?ml$", self.model) and cell_dir is not None and not Path(self.model).is_absolute():
            return str(Path(cell_dir) / self.model)
        return self.model


def robot_section_from_doc(section: Any, source: str = "cell.yaml") -> RobotSection:
    """Validate a ``robot:`` mapping; a bad key raises :class:`RobotSectionError` naming ``robot.<key>``.

    Examples
    --------
    >>> robot_section_from_doc({"model": "irb6600-175-2.55"}).tool.pos_mm
    (0.0, 0.0, 250.0)
    >>> robot_section_from_doc({"tool_nmae": "t"})
    Traceback (most recent call last):
    ...
    doorloc.robot.section.RobotSectionError: cell.yaml: unknown key 'robot.tool_nmae' (robot allows: model, base, tool, tool_name, spindle_axis, tool_tcp_mm, tool_rot, tool_mass_kg, tool_cog_mm, wobj_name, wobj_uframe_mm, wobj_uframe_rot, robconf, travel_speed, travel_zone)
    """
    if section is None:
        section = {}
    if not isinstance(section, dict):
        raise RobotSectionError(
            f"{source}: 'robot' must be a mapping (model, base, tool, ...), got {section!r}"
        )
    try:
        return RobotSection.model_validate(section)
    except ValidationError as e:
        msgs = []
        for err in e.errors(include_url=False):
            loc = tuple(str(p) for p in err["loc"])
            where = ".".join(("robot", *loc))
            if err["type"] == "extra_forbidden":
                allowed = list(Placement.model_fields) if len(loc) > 1 else list(RobotSection.model_fields)
                section_name = ".".join(("robot", *loc[:-1]))
                msgs.append(f"unknown key '{where}' ({section_name} allows: {', '.join(allowed)})")
            else:
                msg = err["msg"].removeprefix("Value error, ")
                msgs.append(f"'{where}': {msg}" if loc else f"robot: {msg}")
        raise RobotSectionError(f"{source}: " + "; ".join(msgs)) from None
