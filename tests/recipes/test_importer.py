"""CSV/XLSX import: one transaction, every bad row named with its line and column; export reads back."""

from __future__ import annotations

from pathlib import Path

import openpyxl
import pytest

from doorloc.recipes.importer import (
    CSV_COLUMNS,
    RecipeImportError,
    import_recipe_file,
    load_recipe_file,
    recipes_to_csv,
)

HEADER = (
    "door_id,width_mm,height_mm,thickness_mm,hinge_z_mm,hinge_length_mm,hinge_width_mm,hinge_x_mm,"
    "hinge_depth_mm,hinge_corner_radius_mm,tool_diameter_mm,spindle_rpm,feed_mm_s"
)
GOOD = [
    "A-1,900,2100,50,250,100,30,10,3,8,16,18000,25",
    "A-1,900,2100,50,1000,100,30,10,3,8,16,18000,25",
    "A-1,900,2100,50,1750,100,30,10,3,8,16,18000,25",
    "B-2,820,2040,40,240,90,25,8,2.5,8,16,18000,20",
    "B-2,820,2040,40,1700,90,25,8,2.5,8,16,18000,20",
]


def _csv(tmp_path: Path, rows: list[str], header: str = HEADER) -> Path:
    p = tmp_path / "recipes.csv"
    p.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")
    return p


def test_import_good_file(store, tmp_path):
    report = import_recipe_file(_csv(tmp_path, GOOD), store)
    assert (report.doors, report.hinges) == (2, 5)
    a = store.get("A-1")
    assert [h.z_mm for h in a.hinges] == [250, 1000, 1750]
    assert store.get("B-2").thickness_mm == 40


def test_three_bad_rows_import_nothing_and_are_named(store, tmp_path):
    store.put_many(load_recipe_file(_csv(tmp_path, GOOD[3:])))  # B-2 is already there
    rows = list(GOOD)
    rows[1] = "A-1,900,2100,50,1000,100,30,10,-3,8,16,18000,25"  # line 3: negative depth
    rows[3] = "B-2,820,2040,40,240,90,35,8,2.5,8,16,18000,20"  # line 5: pocket wider than thickness
    rows.append("C-3,900,2100,50,250,100,30,10,3,8,20,18000,25")  # line 7: tool too big for the corner
    path = _csv(tmp_path, rows)
    with pytest.raises(RecipeImportError) as ei:
        import_recipe_file(path, store)
    err = ei.value
    assert sorted({i.line for i in err.issues}) == [3, 5, 7]
    by_line = {i.line: i for i in err.issues}
    assert by_line[3].column == "hinge_depth_mm" and "greater than 0" in by_line[3].message
    assert by_line[5].column == "hinge_width_mm" and "thickness" in by_line[5].message
    assert by_line[7].column == "tool_diameter_mm" and "corner radius" in by_line[7].message
    assert "3 bad row(s), nothing imported" in str(err)
    assert "line 3, hinge_depth_mm" in str(err)
    # nothing written: A-1 and C-3 absent, the B-2 already stored untouched
    assert store.door_ids() == ["B-2"]
    assert store.get("B-2").hinges[0].width_mm == 25


def test_conflicting_door_fields_are_named(tmp_path):
    rows = [GOOD[0], GOOD[1].replace("A-1,900,2100,50", "A-1,910,2100,50")]
    with pytest.raises(RecipeImportError) as ei:
        load_recipe_file(_csv(tmp_path, rows))
    (issue,) = ei.value.issues
    assert (issue.line, issue.column) == (3, "width_mm")
    assert "differs from 900.0 on line 2" in issue.message


def test_missing_columns_and_empty_files(tmp_path):
    with pytest.raises(RecipeImportError, match="missing column.*hinge_depth_mm"):
        load_recipe_file(_csv(tmp_path, GOOD, header=HEADER.replace(",hinge_depth_mm", "")))
    with pytest.raises(RecipeImportError, match="no rows"):
        load_recipe_file(_csv(tmp_path, []))
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    with pytest.raises(RecipeImportError, match="empty"):
        load_recipe_file(empty)
    with pytest.raises(ValueError, match="give a .csv or .xlsx"):
        load_recipe_file(tmp_path / "recipes.json")


def test_missing_and_non_numeric_values(tmp_path):
    rows = [GOOD[0].replace(",250,", ",,"), GOOD[1].replace(",18000,", ",fast,")]
    with pytest.raises(RecipeImportError) as ei:
        load_recipe_file(_csv(tmp_path, rows))
    got = {(i.line, i.column): i.message for i in ei.value.issues}
    assert got[(2, "hinge_z_mm")] == "missing value"
    assert "valid number" in got[(3, "spindle_rpm")] and "'fast'" in got[(3, "spindle_rpm")]


def test_force_displacement_columns(tmp_path):
    header = HEADER + ",hinge_path_points,hinge_fd_dz_mm,hinge_fd_dy_mm"
    dz = ";".join(str(0.1 + k / 100) for k in range(9))
    rows = [GOOD[0] + ",9," + dz + ",", GOOD[1] + ",6,0.1;0.2,"]
    with pytest.raises(RecipeImportError) as ei:
        load_recipe_file(_csv(tmp_path, rows, header))
    (issue,) = ei.value.issues
    assert issue.line == 3 and "one correction per pocket point" in issue.message
    rows[1] = GOOD[1] + ",6,,"
    (r,) = load_recipe_file(_csv(tmp_path, rows, header))
    assert [c.dz_mm for c in r.hinges[0].corrections] == pytest.approx([0.1 + k / 100 for k in range(9)])
    assert all(c.dx_mm == 0 and c.dy_mm == 0 for c in r.hinges[0].corrections)
    assert r.hinges[1].corrections == ()


def test_xlsx_import_with_numeric_door_ids(store, tmp_path):
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.append(HEADER.split(","))
    for row in GOOD[:3]:
        vals = [float(v) for v in row.split(",")[1:]]
        ws.append([12345, *vals])
    ws.append([None] * 13)  # blank rows are skipped
    bad = [12346, 900, 2100, 50, 250, 100, 30, 10, 3, 8, 16, 18000, -25]
    ws.append(bad)
    path = tmp_path / "recipes.xlsx"
    wb.save(path)
    with pytest.raises(RecipeImportError) as ei:
        import_recipe_file(path, store)
    assert [(i.line, i.column) for i in ei.value.issues] == [(6, "feed_mm_s")]
    ws.delete_rows(6)
    wb.save(path)
    report = import_recipe_file(path, store)
    assert report.door_ids == ["12345"] and store.get("12345").hinges[2].z_mm == 1750


def test_export_reads_back_identically(store, tmp_path, recipe_factory):
    recipes = [
        recipe_factory("E-1"),
        recipe_factory("E-2", arris_mm=0.0, tool_diameter_mm=15.7, feed_mm_s=0.1 + 0.2),
    ]
    store.put_many(recipes)
    text = recipes_to_csv(store.iter_recipes())
    assert text.splitlines()[0] == ",".join(CSV_COLUMNS)
    out = tmp_path / "export.csv"
    out.write_text(text)
    assert load_recipe_file(out) == recipes


def test_damaged_xlsx_is_a_clear_cli_error(tmp_path):
    from typer.testing import CliRunner

    from doorloc.app.cli import app

    bad = tmp_path / "broken.xlsx"
    bad.write_bytes(b"PK\x03\x04 not really a workbook")
    r = CliRunner().invoke(app, ["recipes", "import", str(bad), "--db", f"sqlite:///{tmp_path / 'x.db'}"])
    assert r.exit_code == 2 and "cannot read" in r.stderr and "Traceback" not in r.output
