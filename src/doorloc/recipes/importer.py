"""Recipe files (CSV or XLSX, one row per hinge, door fields repeated) to validated recipes, and back.

Columns (SPEC section 6; header names are case-insensitive, extra columns are ignored)::

    door_id,width_mm,height_mm,thickness_mm,hinge_z_mm,hinge_length_mm,hinge_width_mm,hinge_x_mm,
    hinge_depth_mm,hinge_corner_radius_mm,tool_diameter_mm,spindle_rpm,feed_mm_s

optional: ``arris_mm`` (default 0), ``hinge_path_points`` (6 or 9, default 6) and the
force-displacement corrections ``hinge_fd_dx_mm``, ``hinge_fd_dy_mm``, ``hinge_fd_dz_mm``: each
empty, or one value per pocket point P1..Pn separated by ``;`` (door frame, mm).

A file is all or nothing: :func:`parse_recipe_rows` checks every row and every recipe and raises
:class:`RecipeImportError` listing each problem with its line number (the header is line 1) and
column; only a clean file reaches the database, in one transaction (:meth:`RecipeStore.put_many`).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from doorloc.limits import DEFAULT_MILLING_LIMITS, MillingLimits
from doorloc.recipes.models import MILLING, SKIP_CROSS_CHECKS, DoorFields, DoorRecipe, Hinge, recipe_problems

__all__ = [
    "DOOR_COLUMNS",
    "HINGE_COLUMNS",
    "REQUIRED_COLUMNS",
    "CSV_COLUMNS",
    "ImportIssue",
    "RecipeImportError",
    "read_rows",
    "parse_recipe_rows",
    "load_recipe_file",
    "import_recipe_file",
    "ImportReport",
    "recipes_to_csv",
    "recipe_rows",
]

DOOR_COLUMNS = (
    "door_id",
    "width_mm",
    "height_mm",
    "thickness_mm",
    "arris_mm",
    "tool_diameter_mm",
    "spindle_rpm",
    "feed_mm_s",
)
HINGE_COLUMNS = (
    "hinge_z_mm",
    "hinge_length_mm",
    "hinge_width_mm",
    "hinge_x_mm",
    "hinge_depth_mm",
    "hinge_corner_radius_mm",
    "hinge_path_points",
)
CORRECTION_COLUMNS = ("hinge_fd_dx_mm", "hinge_fd_dy_mm", "hinge_fd_dz_mm")
OPTIONAL_COLUMNS = ("arris_mm", "hinge_path_points", *CORRECTION_COLUMNS)
CSV_COLUMNS = (*DOOR_COLUMNS, *HINGE_COLUMNS, *CORRECTION_COLUMNS)
REQUIRED_COLUMNS = tuple(c for c in CSV_COLUMNS if c not in OPTIONAL_COLUMNS)
#: stop collecting after this many problems (a wrong file would otherwise list thousands)
MAX_ISSUES = 1000


@dataclass(frozen=True, order=True)
class ImportIssue:
    """One problem in a recipe file: ``line`` (1 = header), ``column`` (None: the whole row/file)."""

    line: int
    column: str | None
    message: str

    def __str__(self) -> str:
        return f"line {self.line}" + (f", {self.column}" if self.column else "") + f": {self.message}"


class RecipeImportError(ValueError):
    """A recipe file with problems; nothing of it was imported. ``issues`` lists them all."""

    def __init__(self, source: str, issues: list[ImportIssue]) -> None:
        self.source = source
        self.issues = sorted(issues)
        bad_lines = sorted({i.line for i in self.issues})
        more = "" if len(issues) < MAX_ISSUES else f" (stopped after {MAX_ISSUES} problems)"
        super().__init__(
            f"{source}: {len(bad_lines)} bad row(s), nothing imported{more}:\n"
            + "\n".join(f"  {i}" for i in self.issues)
        )


@dataclass(frozen=True)
class ImportReport:
    """What an import wrote."""

    source: str
    doors: int
    hinges: int
    door_ids: list[str] = field(default_factory=list, repr=False)


# -- reading the table ---------------------------------------------------------------------------
def _clean(v: Any) -> Any:
    """Cell value: strings stripped, empty cells None, whole floats of ids kept as numbers."""
    if v is None:
        return None
    if isinstance(v, str):
        v = v.strip()
        return v or None
    if isinstance(v, float) and math.isnan(v):
        return None
    return v


def _read_csv(path: Path) -> Iterator[tuple[int, dict[str, Any]]]:
    with path.open(newline="", encoding="utf-8-sig") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            return
        names = [h.strip().lower() for h in header]
        yield 1, {"__header__": names}
        for row in reader:
            if not any(c.strip() for c in row):
                continue
            rec = {n: _clean(v) for n, v in zip(names, row, strict=False)}
            if len(row) > len(names):
                rec["__extra__"] = len(row) - len(names)
            yield reader.line_num, rec


def _read_xlsx(path: Path) -> Iterator[tuple[int, dict[str, Any]]]:
    import openpyxl

    wb = openpyxl.load_workbook(path, read_only=True, data_only=True)
    try:
        ws = wb.worksheets[0]
        rows = ws.iter_rows(values_only=True)
        header = next(rows, None)
        if header is None:
            return
        names = [str(h).strip().lower() if h is not None else "" for h in header]
        yield 1, {"__header__": names}
        for line, row in enumerate(rows, start=2):
            if all(c is None or (isinstance(c, str) and not c.strip()) for c in row):
                continue
            yield line, {n: _clean(v) for n, v in zip(names, row, strict=False) if n}
    finally:
        wb.close()


def read_rows(path: str | os.PathLike) -> Iterator[tuple[int, dict[str, Any]]]:
    """``(line, row)`` pairs of a CSV or XLSX recipe file; the first pair carries ``{"__header__": names}``."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in (".xlsx", ".xlsm"):
        return _read_xlsx(p)
    if suffix in (".csv", ".txt"):
        return _read_csv(p)
    raise ValueError(f"{p}: unknown recipe file type {suffix!r}; give a .csv or .xlsx file")


# -- validating --------------------------------------------------------------------------------
def _hinge_column(field_name: str) -> str:
    if field_name == "corrections":
        return "hinge_fd_dx_mm/hinge_fd_dy_mm/hinge_fd_dz_mm"
    return "hinge_" + field_name


def _pydantic_issues(err: ValidationError, line: int, column_of) -> list[ImportIssue]:
    out = []
    for e in err.errors(include_url=False):
        loc = e.get("loc") or ()
        col = column_of(str(loc[0])) if loc else None
        msg = e["msg"]
        if e["type"] == "missing":
            msg = "missing value"
        elif e["type"] == "string_pattern_mismatch" and loc and loc[0] == "door_id":
            msg = "door id must be 1-64 letters, digits or -_./: and start with a letter or digit"
        elif "input" in e and e["type"] != "value_error":
            msg = f"{msg} (got {e['input']!r})"
        out.append(ImportIssue(line, col, msg.removeprefix("Value error, ")))
    return out


def _door_id_text(v: Any) -> Any:
    # spreadsheets turn numeric barcodes into numbers: 12345.0 is the id "12345"
    if isinstance(v, float) and v.is_integer():
        return str(int(v))
    if isinstance(v, int):
        return str(v)
    return v


def _corrections(row: dict[str, Any], line: int) -> tuple[list[dict[str, float]] | None, list[ImportIssue]]:
    issues: list[ImportIssue] = []
    axes: dict[str, list[float]] = {}
    for col, axis in zip(CORRECTION_COLUMNS, ("dx_mm", "dy_mm", "dz_mm"), strict=True):
        v = row.get(col)
        if v is None:
            continue
        parts = [v] if isinstance(v, int | float) else [p.strip() for p in str(v).split(";")]
        try:
            axes[axis] = [float(p) for p in parts]
        except ValueError:
            issues.append(ImportIssue(line, col, f"expected numbers separated by ';', got {v!r}"))
    if issues or not axes:
        return None, issues
    lengths = {len(v) for v in axes.values()}
    if len(lengths) > 1:
        cols = ", ".join(
            f"{CORRECTION_COLUMNS[('dx_mm', 'dy_mm', 'dz_mm').index(a)]}={len(v)}" for a, v in axes.items()
        )
        return None, [
            ImportIssue(
                line,
                "hinge_fd_dx_mm/hinge_fd_dy_mm/hinge_fd_dz_mm",
                f"give the same number of values in each correction column ({cols})",
            )
        ]
    n = lengths.pop()
    return [{a: axes[a][k] for a in axes} for k in range(n)], []


def _path_points(v: Any) -> Any:
    if v is None:
        return 6
    try:
        f = float(v)
    except (TypeError, ValueError):
        return v
    return int(f) if f.is_integer() else v


@dataclass
class _DoorGroup:
    first_line: int
    fields: DoorFields
    hinges: list[Hinge] = field(default_factory=list)
    lines: list[int] = field(default_factory=list)


def parse_recipe_rows(
    rows: Iterable[tuple[int, dict[str, Any]]],
    source: str = "recipe file",
    milling: MillingLimits = DEFAULT_MILLING_LIMITS,
) -> list[DoorRecipe]:
    """Validate table rows into recipes, or raise :class:`RecipeImportError` listing every problem.

    Parameters
    ----------
    rows : iterable of (line, dict)
        From :func:`read_rows`: the first item is ``(1, {"__header__": [column names]})``.
    source : str
        Name used in the error message.
    milling : MillingLimits
        The cell's spindle speed range, feeds and cutter reach (doorloc's defaults without a cell).
    """
    it = iter(rows)
    first = next(it, None)
    if first is None or "__header__" not in first[1]:
        raise RecipeImportError(source, [ImportIssue(1, None, "the file is empty; expected a header row")])
    header = first[1]["__header__"]
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise RecipeImportError(source, [ImportIssue(1, None, f"missing column(s): {', '.join(missing)}")])
    dup_cols = sorted({h for h in header if h and header.count(h) > 1})
    if dup_cols:
        raise RecipeImportError(
            source, [ImportIssue(1, None, f"column(s) given twice: {', '.join(dup_cols)}")]
        )

    issues: list[ImportIssue] = []
    doors: dict[str, _DoorGroup] = {}
    any_rows = False
    for line, row in it:
        any_rows = True
        if len(issues) >= MAX_ISSUES:
            break
        if row.get("__extra__"):
            issues.append(ImportIssue(line, None, f"{row['__extra__']} more value(s) than header columns"))
            continue
        door_part = {c: row.get(c) for c in DOOR_COLUMNS if row.get(c) is not None}
        if "door_id" in door_part:
            door_part["door_id"] = _door_id_text(door_part["door_id"])
        row_issues: list[ImportIssue] = []
        try:
            fields = DoorFields.model_validate(door_part, context={MILLING: milling})
        except ValidationError as e:
            fields = None
            row_issues += _pydantic_issues(e, line, lambda f: f)
        corrections, corr_issues = _corrections(row, line)
        row_issues += corr_issues
        hinge_part: dict[str, Any] = {
            c.removeprefix("hinge_"): row.get(c) for c in HINGE_COLUMNS if row.get(c) is not None
        }
        hinge_part["path_points"] = _path_points(row.get("hinge_path_points"))
        if corrections is not None:
            hinge_part["corrections"] = corrections
        try:
            hinge = Hinge.model_validate(hinge_part)
        except ValidationError as e:
            hinge = None
            row_issues += _pydantic_issues(e, line, _hinge_column)
        if row_issues or fields is None or hinge is None:
            issues += row_issues
            continue
        group = doors.get(fields.door_id)
        if group is None:
            doors[fields.door_id] = _DoorGroup(line, fields, [hinge], [line])
            continue
        if fields != group.fields:
            a, b = group.fields.model_dump(), fields.model_dump()
            for k in DOOR_COLUMNS:
                if a[k] != b[k]:
                    issues.append(
                        ImportIssue(
                            line,
                            k,
                            f"door {fields.door_id}: {b[k]!r} differs from "
                            f"{a[k]!r} on line {group.first_line}",
                        )
                    )
            continue
        group.hinges.append(hinge)
        group.lines.append(line)
    if not any_rows:
        issues.append(ImportIssue(1, None, "the file has a header but no rows"))

    recipes: list[DoorRecipe] = []
    for door_id, g in doors.items():
        if len(g.hinges) > 20:
            issues.append(ImportIssue(g.lines[20], None, f"door {door_id}: more than 20 hinges"))
            continue
        data = {**g.fields.model_dump(), "hinges": g.hinges}
        recipe = DoorRecipe.model_validate(data, context={SKIP_CROSS_CHECKS: True, MILLING: milling})
        problems = recipe_problems(recipe, milling)
        for p in problems:
            line = g.lines[p.hinge] if p.hinge is not None else g.first_line
            name = p.field.split(".")[-1]
            column = _hinge_column(name) if p.field.startswith("hinges[") else name
            issues.append(ImportIssue(line, column, p.message))
        if not problems:
            recipes.append(recipe)
    if issues:
        raise RecipeImportError(source, issues[:MAX_ISSUES])
    return recipes


def load_recipe_file(
    path: str | os.PathLike, milling: MillingLimits = DEFAULT_MILLING_LIMITS
) -> list[DoorRecipe]:
    """Read and validate a whole CSV/XLSX recipe file (nothing is written anywhere) against the cell's
    spindle and cutter bounds ``milling`` (:attr:`doorloc.cell.Cell.milling`)."""
    p = Path(path)
    try:
        return parse_recipe_rows(read_rows(p), str(p), milling)
    except UnicodeDecodeError as e:
        raise RecipeImportError(
            str(p), [ImportIssue(1, None, f"not UTF-8 text ({e.reason}); save the CSV as UTF-8")]
        ) from None
    except csv.Error as e:
        raise RecipeImportError(str(p), [ImportIssue(1, None, f"not a readable CSV file ({e})")]) from None


def import_recipe_file(path: str | os.PathLike, store) -> ImportReport:  # noqa: ANN001 - RecipeStore, lazily typed
    """Validate ``path`` completely, then write all its recipes in one transaction (or none)."""
    recipes = load_recipe_file(path)
    store.put_many(recipes)
    return ImportReport(
        str(path), len(recipes), sum(len(r.hinges) for r in recipes), [r.door_id for r in recipes]
    )


# -- writing -----------------------------------------------------------------------------------
def _num(v: float) -> str:
    return repr(float(v)) if not float(v).is_integer() else str(int(v))


def recipe_rows(recipe: DoorRecipe) -> list[dict[str, str]]:
    """The recipe as import-file rows (one per hinge), values as text that reads back exactly."""
    door = {c: (recipe.door_id if c == "door_id" else _num(getattr(recipe, c))) for c in DOOR_COLUMNS}
    rows = []
    for h in recipe.hinges:
        row = dict(door)
        for c in HINGE_COLUMNS:
            row[c] = _num(getattr(h, c.removeprefix("hinge_")))
        for c, axis in zip(CORRECTION_COLUMNS, ("dx_mm", "dy_mm", "dz_mm"), strict=True):
            values = [getattr(k, axis) for k in h.corrections]
            row[c] = ";".join(_num(v) for v in values) if any(values) else ""
        rows.append(row)
    return rows


def recipes_to_csv(recipes: Iterable[DoorRecipe]) -> str:
    """CSV text in the import layout (``doorloc recipes export``); importing it gives the same recipes."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(CSV_COLUMNS), lineterminator="\n")
    w.writeheader()
    for r in recipes:
        w.writerows(recipe_rows(r))
    return buf.getvalue()
