"""Files the ABB controller reads: the line-by-line target file and a complete RAPID module.

Numbers are written for RAPID's ``num`` (IEEE single precision, about 7 significant digits): at
most 7 significant digits, positional notation, ``.`` decimals, no exponent, no ``-0``; unused
external axes are ``9E+09``. Positions below 10 m therefore keep at least three decimals (0.5 um).

**Text file** (the thesis's file read with ``ReadStr``, section 3.8): line 1 is the number of
targets, then one target per line::

    NAME;X;Y;Z;Q1;Q2;Q3;Q4

``;`` separators, cell frame, mm; every line at most 80 characters (``ReadStr`` reads at most 80).

**Module**: ``MODULE`` with the tooldata and wobjdata of the cell (:class:`RobotSetup`, from the
cell file's optional ``robot:`` section), a ``speeddata`` from the recipe's feed rate, one
``CONST robtarget`` per target and ``PROC MillHinges()`` moving through them with ``MoveL``:
``fine`` at the pocket corners, ``z0`` along the edges (thesis: "the zone is set to z0 or fine").
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from doorloc.pose import DoorPose
from doorloc.recipes.models import DoorRecipe
from doorloc.recipes.targets import Target
from doorloc.robot.section import RobotSection, robot_section_from_doc

__all__ = [
    "RAPID_LINE_MAX",
    "rapid_num",
    "rapid_text",
    "parse_rapid_text",
    "RobotSetup",
    "robot_setup_from_cell_file",
    "rapid_module",
    "module_name_for",
]

#: longest line ``ReadStr`` returns
RAPID_LINE_MAX = 80
#: value RAPID uses for an external axis that is not there
UNUSED_AXIS = "9E+09"
_IDENT = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,31}$")

Quat = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]


def rapid_num(value: float, significant: int = 7, max_decimals: int = 9) -> str:
    """Format a number for RAPID's single-precision ``num``: 7 significant digits, at most 9 decimals.

    Values below ``0.5e-9`` in magnitude are written as ``0`` (far below what a single-precision
    quaternion component or a position in mm can carry).

    Examples
    --------
    >>> rapid_num(1234.56789), rapid_num(-0.0174524064), rapid_num(-0.0), rapid_num(25.0)
    ('1234.568', '-0.01745241', '0', '25')
    """
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"cannot write {v!r} as a RAPID num")
    v = round(v, max_decimals)
    if v == 0.0:
        return "0"
    s = np.format_float_positional(v, precision=significant, unique=False, fractional=False, trim="-")
    return "0" if s in ("-0", "0") else s


def _check_name(name: str) -> str:
    if not _IDENT.match(name):
        raise ValueError(
            f"{name!r} is not a RAPID identifier (a letter, then letters, digits or _; at most 32)"
        )
    return name


def _target_line(t: Target) -> str:
    return ";".join([_check_name(t.name), *(rapid_num(v) for v in (t.x_mm, t.y_mm, t.z_mm, *t.quat))])


def rapid_text(targets: list[Target]) -> str:
    """The line-by-line target file: the count, then ``NAME;X;Y;Z;Q1;Q2;Q3;Q4`` per target.

    Raises
    ------
    ValueError
        If a line would exceed :data:`RAPID_LINE_MAX` characters or a name is not a RAPID identifier.
    """
    lines = [str(len(targets))] + [_target_line(t) for t in targets]
    for ln in lines:
        if len(ln) > RAPID_LINE_MAX:
            raise ValueError(f"RAPID text line longer than {RAPID_LINE_MAX} characters: {ln!r}")
    return "\n".join(lines) + "\n"


def parse_rapid_text(text: str) -> list[Target]:
    """Read a file written by :func:`rapid_text` back (``hinge`` from the ``H<n>_`` name prefix)."""
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise ValueError("empty RAPID target file")
    n = int(lines[0])
    if n != len(lines) - 1:
        raise ValueError(f"RAPID target file says {n} targets but holds {len(lines) - 1}")
    out = []
    for ln in lines[1:]:
        f = ln.split(";")
        if len(f) != 8:
            raise ValueError(f"RAPID target line needs 8 ';'-separated fields: {ln!r}")
        m = re.match(r"^H(\d+)_", f[0])
        out.append(
            Target(
                name=f[0],
                x_mm=float(f[1]),
                y_mm=float(f[2]),
                z_mm=float(f[3]),
                quat=tuple(float(v) for v in f[4:8]),
                hinge=int(m.group(1)) if m else 0,
            )
        )
    return out


#: the cell file's ``robot:`` section (doorloc.robot.section): RAPID tool/work-object data plus the robot
#: model, base placement and tool that the reach check uses; one model, so the two never disagree
RobotSetup = RobotSection


def robot_setup_from_cell_file(path: str | Path) -> RobotSetup:
    """The ``robot:`` section of a cell file (defaults where it or a key is absent).

    Raises
    ------
    doorloc.robot.section.RobotSectionError
        A misspelt or bad key (the message names ``robot.<key>``).
    """
    import yaml

    doc = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    section = doc.get("robot") if isinstance(doc, dict) else None
    return robot_section_from_doc(section or {}, str(path))


def _vec(v) -> str:
    return "[" + ",".join(rapid_num(x) for x in v) + "]"


def module_name_for(door_id: str) -> str:
    """A RAPID module name for a door: ``Door_`` and the id with non-identifier characters as ``_``."""
    return ("Door_" + re.sub(r"[^A-Za-z0-9_]", "_", door_id))[:32]


def rapid_module(
    recipe: DoorRecipe,
    targets: list[Target],
    robot: RobotSetup | None = None,
    *,
    pose: DoorPose | None = None,
    face_y_mm: float | None = None,
    module_name: str | None = None,
) -> str:
    """A complete RAPID module milling the recipe's hinge pockets through ``targets``.

    Parameters
    ----------
    recipe : DoorRecipe
        Gives the feed (``speeddata vMill``), spindle speed (comment) and door id.
    targets : list of Target
        From :func:`doorloc.recipes.targets.targets_for_pose`, cell frame.
    robot : RobotSetup, optional
        Tooldata and wobjdata; defaults to :class:`RobotSetup()`.
    pose, face_y_mm : optional
        Only written into the header comment, for the record.
    module_name : str, optional
        Defaults to :func:`module_name_for` the door id.
    """
    robot = robot or RobotSetup()
    name = _check_name(module_name or module_name_for(recipe.door_id))
    tool, wobj = robot.tool_name, robot.wobj_name
    lines = [f"MODULE {name}"]
    lines.append(
        f"  ! doorloc hinge targets for door {recipe.door_id}: {len(recipe.hinges)} hinge(s), "
        f"{len(targets)} targets, cell frame, mm"
    )
    if pose is not None:
        fy = "" if face_y_mm is None else f" face_y={rapid_num(face_y_mm)}"
        lines.append(
            f"  ! pose x={rapid_num(pose.x_mm)} z={rapid_num(pose.z_mm)} yaw={rapid_num(pose.yaw_deg)} deg{fy}"
        )
    lines.append(
        f"  ! tool diameter {rapid_num(recipe.tool_diameter_mm)} mm, spindle {rapid_num(recipe.spindle_rpm)} rpm, "
        f"feed {rapid_num(recipe.feed_mm_s)} mm/s"
    )
    lines.append(
        f"  PERS tooldata {tool}:=[TRUE,[{_vec(robot.tool_tcp_mm)},{_vec(robot.tool_rot)}],"
        f"[{rapid_num(robot.tool_mass_kg)},{_vec(robot.tool_cog_mm)},[1,0,0,0],0,0,0]];"
    )
    lines.append(
        f'  PERS wobjdata {wobj}:=[FALSE,TRUE,"",[{_vec(robot.wobj_uframe_mm)},{_vec(robot.wobj_uframe_rot)}],'
        f"[[0,0,0],[1,0,0,0]]];"
    )
    lines.append(f"  CONST speeddata vMill:=[{rapid_num(recipe.feed_mm_s)},500,5000,1000];")
    conf = "[" + ",".join(str(c) for c in robot.robconf) + "]"
    ext = "[" + ",".join([UNUSED_AXIS] * 6) + "]"
    for t in targets:
        lines.append(
            f"  CONST robtarget {_check_name(t.name)}:=[{_vec((t.x_mm, t.y_mm, t.z_mm))},{_vec(t.quat)},{conf},{ext}];"
        )
    lines.append("")
    lines.append("  PROC MillHinges()")
    lines.append(
        f"    ! start the spindle ({rapid_num(recipe.spindle_rpm)} rpm) before calling; cell-specific I/O"
    )
    lines.append("    ConfL\\Off;")
    previous = None
    for t in targets:
        if t.kind == "approach":
            speed, zone = robot.travel_speed, robot.travel_zone
        else:
            # the plunge ends with a stop at the pocket bottom before the tool moves sideways
            plunge = previous is not None and previous.kind == "approach"
            speed, zone = "vMill", ("z0" if t.kind == "edge" and not plunge else "fine")
        previous = t
        lines.append(f"    MoveL {t.name},{speed},{zone},{tool}\\WObj:={wobj};")
    lines.append("    ConfL\\On;")
    lines.append("  ENDPROC")
    lines.append("ENDMODULE")
    return "\n".join(lines) + "\n"
