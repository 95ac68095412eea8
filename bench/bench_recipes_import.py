"""Benchmark: import a 10,000-door recipe CSV (3 hinges per door: 30,000 rows) into the recipe database.

Prints the time to read + validate the file, the time of the one-transaction bulk write, the total,
and the same through the command line (`doorloc recipes import`, process start included). Then shows
that a file with 3 bad rows imports nothing and names the 3 rows.

    python bench/bench_recipes_import.py                      # SQLite file in a temp dir
    python bench/bench_recipes_import.py --db postgresql+psycopg://doorloc:doorloc@127.0.0.1/doorloc_test
    python bench/bench_recipes_import.py --doors 10000 --hinges 3

With --db the benchmark writes into that database (doors BENCH-00000...; removed again at the end).
"""

from __future__ import annotations

import argparse
import csv
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from doorloc.recipes.importer import REQUIRED_COLUMNS, RecipeImportError, import_recipe_file, load_recipe_file
from doorloc.recipes.store import RecipeStore, redacted_url


def write_csv(path: Path, doors: int, hinges: int, seed: int = 0) -> int:
    rng = random.Random(seed)
    columns = list(REQUIRED_COLUMNS) + ["arris_mm", "hinge_path_points", "hinge_fd_dz_mm"]
    rows = 0
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for d in range(doors):
            width = rng.choice([626, 726, 826, 926, 1026])
            height = rng.choice([2040, 2100, 2340])
            thick = rng.choice([40, 44, 50, 60])
            door = {
                "door_id": f"BENCH-{d:05d}",
                "width_mm": width,
                "height_mm": height,
                "thickness_mm": thick,
                "tool_diameter_mm": 16,
                "spindle_rpm": 18000,
                "feed_mm_s": 25,
                "arris_mm": 1,
            }
            for k in range(hinges):
                path9 = k == hinges - 1
                row = dict(
                    door,
                    hinge_z_mm=200 + k * (height - 500) / max(hinges - 1, 1),
                    hinge_length_mm=100,
                    hinge_width_mm=30,
                    hinge_x_mm=round(rng.uniform(5, thick - 31), 1),
                    hinge_depth_mm=3,
                    hinge_corner_radius_mm=8,
                    hinge_path_points=9 if path9 else 6,
                    hinge_fd_dz_mm=";".join(f"{0.1 + 0.01 * p:.2f}" for p in range(9)) if path9 else "",
                )
                w.writerow([row[c] for c in columns])
                rows += 1
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--doors", type=int, default=10_000)
    ap.add_argument("--hinges", type=int, default=3)
    ap.add_argument("--db", default=None, help="database URL (default: a new SQLite file in a temp dir)")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = tmp / "recipes.csv"
        rows = write_csv(src, args.doors, args.hinges)
        url = args.db or f"sqlite:///{tmp / 'bench.db'}"
        print(
            f"file: {args.doors} doors, {rows} hinge rows, {src.stat().st_size / 1e6:.1f} MB; db: {redacted_url(url)}"
        )

        with RecipeStore(url) as store:
            t0 = time.perf_counter()
            recipes = load_recipe_file(src)
            t1 = time.perf_counter()
            store.put_many(recipes)
            t2 = time.perf_counter()
            print(f"read + validate: {t1 - t0:6.2f} s")
            print(f"bulk write (1 transaction): {t2 - t1:6.2f} s")
            print(f"import total (library): {t2 - t0:6.2f} s   [{args.doors / (t2 - t0):,.0f} doors/s]")
            t0 = time.perf_counter()
            report = import_recipe_file(src, store)  # again: identical recipes, so nothing is rewritten
            print(
                f"re-import of the same {report.doors} doors (unchanged: no new versions): {time.perf_counter() - t0:6.2f} s"
            )
            assert store.count() >= args.doors

        exe = Path(sys.executable).with_name("doorloc")
        if exe.exists():
            t0 = time.perf_counter()
            r = subprocess.run(
                [str(exe), "recipes", "import", str(src), "--db", url],
                capture_output=True,
                text=True,
                env={**os.environ, "DOORLOC_DATABASE_URL": ""},
            )
            dt = time.perf_counter() - t0
            print(
                f"doorloc recipes import (CLI, process start included): {dt:6.2f} s  -> {r.stdout.strip() or r.stderr.strip()}"
            )

        if args.db:
            with RecipeStore(url) as store:
                from sqlalchemy import delete

                from doorloc.recipes.tables import DoorRow

                with store.engine.begin() as conn:
                    conn.execute(delete(DoorRow).where(DoorRow.door_id.like("BENCH-%")))

        # a file with 3 bad rows imports nothing and names them
        lines = src.read_text(encoding="utf-8").splitlines()
        bad_lines = {
            101: ("hinge_depth_mm", "-3"),
            5002: ("thickness_mm", "0"),
            29000: ("hinge_width_mm", "300"),
        }
        header = lines[0].split(",")
        for ln, (col, val) in bad_lines.items():
            cells = next(csv.reader([lines[ln - 1]]))
            cells[header.index(col)] = val
            lines[ln - 1] = ",".join(f'"{c}"' if ";" in c else c for c in cells)
        bad = tmp / "bad.csv"
        bad.write_text("\n".join(lines) + "\n", encoding="utf-8")
        fresh = f"sqlite:///{tmp / 'bad.db'}"
        with RecipeStore(fresh) as store:
            try:
                import_recipe_file(bad, store)
                print("3-bad-rows file: IMPORTED (wrong)")
            except RecipeImportError as e:
                named = sorted({i.line for i in e.issues})
                print(
                    f"3-bad-rows file: {store.count()} doors written; rows named: {named} (planted {sorted(bad_lines)})"
                )
                for issue in e.issues:
                    print(f"    {issue}")


if __name__ == "__main__":
    main()
