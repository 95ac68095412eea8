"""Run every Hypothesis test of one test module under many seeds, in one process, and count failures.

Usage: ``python scripts/hypothesis_seeds.py tests/core/test_camera.py [N_SEEDS [NAME_PART]]`` (default 200
seeds; NAME_PART keeps only the tests whose name contains it). Run from the repository root with
``PYTHONPATH=src:tests`` (or the project installed).
The suite draws the same examples on every run (tests/conftest.py); this shows a property holds beyond them.
"""

from __future__ import annotations

import importlib.util
import sys
import traceback
from pathlib import Path

from hypothesis import seed


def main(argv: list[str]) -> int:
    module_path = Path(argv[1])
    n_seeds = int(argv[2]) if len(argv) > 2 else 200
    name_part = argv[3] if len(argv) > 3 else ""
    spec = importlib.util.spec_from_file_location(module_path.stem, module_path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    tests = {
        name: fn
        for name, fn in vars(module).items()
        if name.startswith("test_") and name_part in name and getattr(fn, "is_hypothesis_test", False)
    }
    failed = 0
    for name, fn in tests.items():
        bad = []
        for s in range(n_seeds):
            try:
                seed(s)(fn)()
            except Exception:  # a failing example: report it, go on with the next seed
                bad.append(s)
                if len(bad) == 1:
                    traceback.print_exc(limit=3)
        failed += bool(bad)
        print(
            f"{name}: {n_seeds - len(bad)}/{n_seeds} seeds passed"
            + (f"; failing seeds {bad[:10]}" if bad else "")
        )
    print(f"{len(tests) - failed}/{len(tests)} property tests passed for all {n_seeds} seeds")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
