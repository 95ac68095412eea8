"""Reach check timing and the Table 4.8 deflection against the thesis's 0.3 mm statement.

Prints:

1. the median time of one door's reach check (targets_for_pose + check_reach: all hinges, all targets)
   with the bundled thesis cell, one thread, for the thesis's widest door and the demo door;
2. the TCP deflection ``J K^-1 J^T W`` for each Table 4.8 segment wrench at Table 4.6's four
   configurations, as the thesis's appendix computes it (flange = TCP, wrench in the base frame), and
   the largest deflection along the extreme doors' paths with the bundled cell's angle-head tool.

Run with ``OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_reach.py [--repeat N]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from doorloc.cell import load_cell  # noqa: E402
from doorloc.pose import DoorPose  # noqa: E402
from doorloc.recipes.importer import load_recipe_file  # noqa: E402
from doorloc.robot.deflection import TABLE_4_8_WRENCH, tcp_deflection_mm  # noqa: E402
from doorloc.robot.kinematics import Kinematics  # noqa: E402
from doorloc.robot.reach import reach_for_door, setup_for_cell  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TABLE_4_6 = {
    "bottom hinge, W max": [-13.58, 69.54, 34.97, -14.01, -104.10, -93.48],
    "bottom hinge, W min": [13.58, 69.54, 34.97, 14.01, -104.10, -86.52],
    "top hinge, W max": [-13.58, 6.89, -44.31, 21.68, 39.46, -107.06],
    "top hinge, W min": [13.58, 6.89, -44.31, -21.68, 39.46, -72.94],
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=400, help="timed runs per door")
    args = ap.parse_args()

    cell = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    setup = setup_for_cell(cell)
    assert setup is not None
    doors = load_recipe_file(REPO / "fixtures" / "recipes" / "thesis_extremes.csv")
    doors += load_recipe_file(REPO / "fixtures" / "recipes" / "demo_doors.csv")

    print("1. reach check of one door (targets_for_pose + check_reach), bundled thesis cell, one thread")
    print(
        f"   (load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores: on a shared machine the minimum is the cost)"
    )
    for recipe in doors:
        face_y = cell.face_y(recipe.door_size())
        pose = DoorPose(3.0, -4.0, 1.5)
        rep = reach_for_door(setup, recipe, pose, face_y)  # warm-up
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            reach_for_door(setup, recipe, pose, face_y)
            times.append(time.perf_counter() - t0)
        ms = np.array(times) * 1e3
        print(
            f"   {recipe.door_id:<12} {len(recipe.hinges)} hinges {len(rep.targets):3d} targets: median {statistics.median(ms):.3f} ms"
            f"  (min {ms.min():.3f}, p10 {np.percentile(ms, 10):.3f}, p90 {np.percentile(ms, 90):.3f}), feasible={rep.feasible}"
        )

    print("\n2. TCP deflection under Table 4.8's wrench, |dd| mm (thesis: largest compensation about 0.3 mm)")
    robot, kin = setup.robot, Kinematics.of(setup.robot)
    print(
        "   a) as the thesis's appendix: flange = TCP, wrench in the robot base frame, Table 4.6 configurations"
    )
    print(f"   {'configuration':<22}" + "".join(f"{s:>13}" for s in TABLE_4_8_WRENCH))
    largest = 0.0
    for name, q in TABLE_4_6.items():
        row = []
        for w in TABLE_4_8_WRENCH.values():
            dd = tcp_deflection_mm(robot, kin, np.radians(q), np.zeros(3), np.array(w))
            row.append(float(np.linalg.norm(dd)))
        largest = max(largest, *row)
        print(f"   {name:<22}" + "".join(f"{v:13.3f}" for v in row))
    print(f"   largest: {largest:.3f} mm")
    print(
        "   b) bundled cell (angle head, TCP 250 mm out), wrench in the tool frame, extreme doors at pose (0, 0, 0)"
    )
    for recipe in doors[:2]:
        rep = reach_for_door(setup, recipe, DoorPose(), cell.face_y(recipe.door_size()))
        mags = [(float(np.linalg.norm(t.deflection_mm)), t.name) for t in rep.targets if t.deflection_mm]
        mag, where = max(mags)
        print(f"   {recipe.door_id:<12} largest |dd| {mag:.3f} mm at {where}")


if __name__ == "__main__":
    main()
