"""Schemathesis, all checks, against the in-process app with many more examples than the test suite runs.

    python bench/bench_service_schema.py --examples 300

Prints pytest's verdict per operation and generation mode: any 5xx, undocumented status code or response
that violates its schema fails the operation's line.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--examples", type=int, default=300, help="examples per operation and mode")
    args = ap.parse_args()
    env = {**os.environ, "DOORLOC_SCHEMATHESIS_EXAMPLES": str(args.examples)}
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "tests/app/test_api_schema.py",
            "-q",
            "-rA",
            "-p",
            "no:cacheprovider",
        ],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
    )
    lines = [
        ln for ln in p.stdout.splitlines() if ln.startswith(("PASSED", "FAILED", "ERROR")) or " passed" in ln
    ]
    print(f"schemathesis, all checks, {args.examples} examples per operation and mode:")
    print("\n".join(lines))
    if p.returncode != 0:
        print(p.stdout[-5000:])
    sys.exit(p.returncode)


if __name__ == "__main__":
    main()
