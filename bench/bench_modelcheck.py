"""Benchmark of `check-model`: hidden effects named right, false alarms, held-out gain, time per data set.

Renders measured sets (doorloc.modelcheck.synth: true cell with the effect, reference poses with a few
micrometres of noise, several widths and thicknesses) and runs check_model blind with the nominal cell.

Full acceptance run (issue 12): every catalogue effect twice, 10 controls, 5 two-effect sets::

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_modelcheck.py --repeats 2 --controls 10 --pairs 5

A subset (what fits a shared machine): ``--repeats 1 --controls 3 --pairs 2``. Acceptance: >= 90 % named
right, <= 1 false alarm in 10 controls, median held-out gain >= 5x, <= 10 min per 40-image data set.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from doorloc.cell import load_cell
from doorloc.modelcheck import EFFECT_NAMES, check_model
from doorloc.modelcheck.synth import REALISTIC_RANGE, SetSpec, draw_hidden_effect, render_measured_set

REPO = Path(__file__).resolve().parents[1]


def _draw(name: str, rng: np.random.Generator) -> list[float]:
    return draw_hidden_effect(rng, [name])[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cell", default=str(REPO / "fixtures" / "cell_thesis.yaml"))
    ap.add_argument("--repeats", type=int, default=2, help="data sets per catalogue effect")
    ap.add_argument("--controls", type=int, default=10)
    ap.add_argument("--pairs", type=int, default=5, help="two-effect data sets")
    ap.add_argument("--images", type=int, default=40)
    ap.add_argument(
        "--effects", default=",".join(EFFECT_NAMES), help="comma-separated subset of the catalogue"
    )
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--json", help="write every case's outcome here")
    args = ap.parse_args()
    nominal = load_cell(args.cell)
    rng = np.random.default_rng(args.seed)
    names = [n for n in args.effects.split(",") if n]
    cases: list[dict] = []
    for _ in range(args.repeats):
        for n in names:
            cases.append({"hidden": {n: _draw(n, rng)}})
    for _ in range(args.controls):
        cases.append({"hidden": {}})
    geometric = [n for n in names if n not in ("arris", "response_gamma")]
    for _ in range(args.pairs):
        a, b = rng.choice(geometric, 2, replace=False)
        cases.append({"hidden": {str(a): _draw(str(a), rng), str(b): _draw(str(b), rng)}})
    print(
        f"{len(cases)} data sets of {args.images} images; magnitudes from {json.dumps(REALISTIC_RANGE)}",
        flush=True,
    )
    with tempfile.TemporaryDirectory(prefix="bench_modelcheck_") as tmp:
        for k, case in enumerate(cases):
            data = Path(tmp) / f"set_{k:02d}"
            t0 = time.perf_counter()
            render_measured_set(
                data, nominal, case["hidden"], SetSpec(n_images=args.images, seed=args.seed + k)
            )
            t1 = time.perf_counter()
            rep = check_model(data, nominal, Path(tmp) / f"report_{k:02d}")
            t2 = time.perf_counter()
            hidden = sorted(case["hidden"])
            named = sorted(c for c in rep.causes)
            case.update(
                named=rep.causes,
                right=named == hidden,
                gain=rep.heldout_gain,
                render_s=t1 - t0,
                check_s=t2 - t1,
                before=rep.heldout_rms_before,
                after=rep.heldout_rms_after,
                indistinguishable=rep.indistinguishable,
            )
            print(
                f"[{k + 1}/{len(cases)}] hidden {case['hidden'] or '-'} -> named {rep.causes} "
                f"{'OK' if case['right'] else 'WRONG'}; gain {rep.heldout_gain:.1f}x; check {t2 - t1:.0f} s "
                f"(render {t1 - t0:.0f} s)",
                flush=True,
            )
    effect_cases = [c for c in cases if c["hidden"]]
    controls = [c for c in cases if not c["hidden"]]
    singles = [c for c in effect_cases if len(c["hidden"]) == 1]
    print("\nconfusion (hidden -> named, single-effect sets):")
    table: dict[str, dict[str, int]] = {}
    for c in singles:
        h = next(iter(c["hidden"]))
        got = ",".join(c["named"]) or "[]"
        table.setdefault(h, {}).setdefault(got, 0)
        table[h][got] += 1
    for h in names:
        if h in table:
            print(f"  {h:18s} " + "  ".join(f"{g}: {n}" for g, n in sorted(table[h].items())))
    right = sum(c["right"] for c in effect_cases)
    alarms = sum(bool(c["named"]) for c in controls)
    gains = [c["gain"] for c in effect_cases]
    times = [c["check_s"] for c in cases]
    print(
        f"\nnamed right: {right}/{len(effect_cases)} = {100 * right / max(len(effect_cases), 1):.0f} % "
        f"(singles {sum(c['right'] for c in singles)}/{len(singles)}, "
        f"pairs {sum(c['right'] for c in effect_cases if len(c['hidden']) == 2)}/{len(effect_cases) - len(singles)})"
    )
    print(f"false alarms: {alarms}/{len(controls)} controls")
    if gains:
        print(f"median held-out gain: {statistics.median(gains):.1f}x (min {min(gains):.1f}x)")
    print(
        f"time per data set (check only, {args.images} images, shared 2-core machine): median "
        f"{statistics.median(times):.0f} s, max {max(times):.0f} s"
    )
    if args.json:
        Path(args.json).write_text(json.dumps(cases, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
