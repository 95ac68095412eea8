#!/usr/bin/env python
"""Whole-result parity of locate between two versions of the code: every golden case
(tests/vision/locate_golden.py: the committed fixtures and the inputs derived from them) through
:func:`doorloc.vision.locate.locate`, its whole result (answer, refusal and message, uncertainty, lines,
every diagnostics key but the stage timings) written to a JSON file; ``--compare`` then holds a second
run against the first, numbers within ``--tol`` (absolute), everything else equal, keys added to the
diagnostics allowed (reported).

The golden parity test (tests/vision/test_locate_parity.py) compares poses within 1e-4 mm; this is the
stricter check a restructuring that must change no number is held to.

Run:  OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_vision_parity.py --write before.json
      OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_vision_parity.py --write after.json --compare before.json
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: diagnostics that measure the run, not the answer
SKIP = {"timing_ms", "provenance", "elapsed_ms"}


def _golden():
    spec = importlib.util.spec_from_file_location(
        "locate_golden", REPO / "tests" / "vision" / "locate_golden.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["locate_golden"] = mod
    spec.loader.exec_module(mod)
    return mod


def results() -> dict:
    """``{case name: the result as JSON, the run's timings left out}`` for every golden case."""
    from doorloc.vision.locate import locate

    out = {}
    for name, cell, door, img in _golden().all_cases():
        r = locate(img, cell, door, image_name=name).model_dump(mode="json")
        for k in SKIP:
            r.pop(k, None)
            (r.get("diagnostics") or {}).pop(k, None)
        out[name] = r
    return out


def differences(got, want, tol: float, path: str = "") -> tuple[list[str], list[str]]:
    """(differences, keys added to ``got``) between two results, numbers within ``tol``."""
    diff: list[str] = []
    added: list[str] = []
    if isinstance(want, dict) and isinstance(got, dict):
        for k in want:
            if k not in got:
                diff.append(f"{path}/{k} missing")
            else:
                d, a = differences(got[k], want[k], tol, f"{path}/{k}")
                diff += d
                added += a
        added += [f"{path}/{k}" for k in got if k not in want]
    elif isinstance(want, list) and isinstance(got, list):
        if len(want) != len(got):
            diff.append(f"{path}: {len(got)} items, {len(want)} before")
        else:
            for i, (g, w) in enumerate(zip(got, want, strict=True)):
                d, a = differences(g, w, tol, f"{path}[{i}]")
                diff += d
                added += a
    elif isinstance(want, float | int) and isinstance(got, float | int) and not isinstance(want, bool):
        if not (math.isnan(want) and math.isnan(got)) and not abs(got - want) <= tol:
            diff.append(f"{path}: {got!r} != {want!r}")
    elif got != want:
        diff.append(f"{path}: {got!r} != {want!r}")
    return diff, added


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", required=True, help="where to write this code's results (JSON)")
    ap.add_argument("--compare", help="results written before (JSON) to hold these against")
    ap.add_argument("--tol", type=float, default=1e-9)
    args = ap.parse_args()
    got = results()
    Path(args.write).write_text(json.dumps(got, indent=1, sort_keys=True))
    if not args.compare:
        print(f"{len(got)} cases written to {args.write}")
        return
    want = json.loads(Path(args.compare).read_text())
    bad, added = {}, set()
    for name in sorted(set(want) | set(got)):
        d, a = differences(got.get(name), want.get(name), args.tol)
        added |= {x.split("/", 2)[-1] for x in a}
        if d:
            bad[name] = d
    print(f"{len(want)} cases; {len(bad)} differ beyond {args.tol:g}; keys added: {sorted(added) or 'none'}")
    for name, d in bad.items():
        print(f"  {name}: {'; '.join(d[:5])}{' ...' if len(d) > 5 else ''}")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
