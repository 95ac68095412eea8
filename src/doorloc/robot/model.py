"""Robot files: a 6R arm's DH table, joint limits, stiffness and reach thresholds, with their sources.

A robot file is YAML validated strictly (unknown keys are errors). The bundled robot is the
ABB IRB 6600-175/2.55 (``data/irb6600-175-2.55.yaml``); :func:`load_robot` takes a bundled model
name or a path. docs/robot.md defines every field.
"""

from __future__ import annotations

import math
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Annotated

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

__all__ = [
    "DHLink",
    "Stiffness",
    "RobotModel",
    "RobotFileError",
    "load_robot",
    "bundled_robots",
    "DEFAULT_ROBOT",
]

#: the robot a cell gets when its ``robot:`` section names none, and ``doorloc reach`` without --cell
DEFAULT_ROBOT = "irb6600-175-2.55"

Finite = Annotated[float, Field(allow_inf_nan=False)]


class RobotFileError(ValueError):
    """A robot file that cannot be used; the message names the file and the key."""


class _Strict(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class DHLink(_Strict):
    """One row of a standard DH table: ``Rz(theta_offset + q) Tz(d) Tx(a) Rx(alpha)``; mm and degrees."""

    theta_offset_deg: Finite = 0.0
    d_mm: Finite = 0.0
    a_mm: Finite = 0.0
    alpha_deg: Finite = 0.0


class Stiffness(_Strict):
    """Joint stiffness: ``K_i = joint1_nm_per_rad * ratios[i]`` (Nm/rad), lumped at the joints."""

    joint1_nm_per_rad: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    ratios: tuple[float, float, float, float, float, float]
    source: str = ""

    @model_validator(mode="after")
    def _positive(self) -> Stiffness:
        if not all(r > 0 and math.isfinite(r) for r in self.ratios):
            raise ValueError("stiffness ratios must be positive numbers")
        return self

    def joint_nm_per_rad(self) -> np.ndarray:
        """Diagonal of K_theta, shape (6,), Nm/rad."""
        return self.joint1_nm_per_rad * np.asarray(self.ratios, dtype=float)


class RobotModel(_Strict):
    """A 6R industrial arm with a spherical wrist (ABB/KUKA layout), as a robot file describes it.

    Attributes
    ----------
    name : str
        Human name, e.g. ``IRB6600-175/2.55``.
    model : str
        The key a cell file's ``robot.model`` uses.
    dh : 6 DHLink
        Standard DH, base to flange. The closed-form inverse kinematics needs the layout
        ``alpha = -90, 0, -90, +90, -90, 0`` deg, ``d2 = d3 = d5 = 0``, ``a4 = a5 = a6 = 0``
        (checked on load).
    joint_limits_deg : 6 pairs
        ``[min, max]`` per joint, deg.
    stiffness : Stiffness
    characteristic_length_mm : float
        Divides the position rows of the Jacobian for the singularity measure (docs/robot.md).
    min_inv_condition : float
        A target whose inverse condition number is below this is ``near_singularity``.
    joint_margin_deg : float
        A target closer than this to a joint limit is ``joint_limit``.
    max_joint_step_deg : float
        A joint moving more than this between two neighbouring points of a path is a ``configuration_flip``.
    """

    name: str
    model: str
    dh: tuple[DHLink, DHLink, DHLink, DHLink, DHLink, DHLink]
    dh_source: str = ""
    joint_limits_deg: tuple[tuple[float, float], ...] = Field(min_length=6, max_length=6)
    joint_limit_sources: tuple[str, ...] = ()
    stiffness: Stiffness
    characteristic_length_mm: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    min_inv_condition: Annotated[float, Field(ge=0, lt=1)] = 0.05
    joint_margin_deg: Annotated[float, Field(ge=0, le=30)] = 2.0
    max_joint_step_deg: Annotated[float, Field(gt=0, le=180)] = 45.0

    @model_validator(mode="after")
    def _layout(self) -> RobotModel:
        for i, (lo, hi) in enumerate(self.joint_limits_deg):
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"joint_limits_deg[{i}] must be [min, max] with min < max, got [{lo}, {hi}]")
        alphas = [link.alpha_deg for link in self.dh]
        if alphas != [-90.0, 0.0, -90.0, 90.0, -90.0, 0.0]:
            raise ValueError(
                f"dh: the closed-form inverse kinematics needs alpha = -90, 0, -90, 90, -90, 0 deg, got {alphas}"
            )
        zero = {
            "dh[1].d_mm": self.dh[1].d_mm,
            "dh[2].d_mm": self.dh[2].d_mm,
            "dh[4].d_mm": self.dh[4].d_mm,
            "dh[3].a_mm": self.dh[3].a_mm,
            "dh[4].a_mm": self.dh[4].a_mm,
            "dh[5].a_mm": self.dh[5].a_mm,
        }
        bad = [k for k, v in zero.items() if v != 0.0]
        if bad:
            raise ValueError(f"{', '.join(bad)} must be 0 for a spherical wrist without shoulder offsets")
        if self.joint_limit_sources and len(self.joint_limit_sources) != 6:
            raise ValueError("joint_limit_sources: give one source per joint (6) or none")
        return self

    def limits_rad(self) -> np.ndarray:
        """Joint limits, shape (6, 2), radians."""
        return np.radians(np.asarray(self.joint_limits_deg, dtype=float))


def bundled_robots() -> list[str]:
    """Model names of the robot files shipped with doorloc."""
    folder = resources.files("doorloc.robot") / "data"
    return sorted(p.name.removesuffix(".yaml") for p in folder.iterdir() if p.name.endswith(".yaml"))


def _parse(text: str, source: str) -> RobotModel:
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise RobotFileError(f"{source}: not valid YAML: {e}") from None
    if not isinstance(doc, dict):
        raise RobotFileError(f"{source}: a robot file is a mapping of keys (name, model, dh, ...)")
    try:
        return RobotModel.model_validate(doc)
    except ValidationError as e:
        first = e.errors(include_url=False)[0]
        where = ".".join(str(p) for p in first["loc"]) or "(top level)"
        raise RobotFileError(f"{source}: {where}: {first['msg']}") from None


@lru_cache(maxsize=16)
def _bundled(name: str) -> RobotModel:
    text = (resources.files("doorloc.robot") / "data" / f"{name}.yaml").read_text(encoding="utf-8")
    return _parse(text, f"bundled robot {name}")


def load_robot(name_or_path: str | Path = DEFAULT_ROBOT) -> RobotModel:
    """A bundled robot by model name (``irb6600-175-2.55``) or a robot file by path.

    Raises
    ------
    RobotFileError
        Unknown model name, unreadable file or a file that breaks the rules (the message names the key).
    """
    s = str(name_or_path)
    if s in bundled_robots():
        return _bundled(s)
    p = Path(s)
    if p.suffix in (".yaml", ".yml") and p.is_file():
        try:
            return _parse(p.read_text(encoding="utf-8"), str(p))
        except OSError as e:
            raise RobotFileError(f"{p}: cannot read robot file: {e}") from None
    raise RobotFileError(
        f"unknown robot {s!r}: give a robot file (.yaml) or one of {', '.join(bundled_robots())}"
    )
