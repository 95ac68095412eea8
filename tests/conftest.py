"""Shared test helpers: where the repository and the real data live; Hypothesis profiles."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings
from hypothesis.database import DirectoryBasedExampleDatabase

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"

# Hypothesis profiles. The suite's verdict must not change from run to run on the same code: CI lands
# nothing on a red run, and a new user's first run must not fail on a draw nobody has seen. So the
# default draws the same examples on every run and machine (derandomized: seeded from each test itself);
# a property is tried beyond them on purpose, by "explore" or by many seeds in one go
# (``python scripts/hypothesis_seeds.py tests/core/test_camera.py 200``), and what that finds is fixed in
# the code and, where it teaches something, pinned as an ``@example``.
# - "dev" (default) and "ci": derandomized, no example database.
# - "explore": random exploration (new inputs on every run) with the example database
#   (.hypothesis/examples/, git-ignored, shared by xdist workers): a failure found once is replayed first
#   on every later run until it is fixed, and its report carries a ``@reproduce_failure`` blob.
# Pick one with ``pytest --hypothesis-profile=NAME`` or DOORLOC_HYPOTHESIS_PROFILE=NAME.
_EXAMPLES = DirectoryBasedExampleDatabase(str(REPO / ".hypothesis" / "examples"))
settings.register_profile("dev", database=None, derandomize=True, print_blob=True)
settings.register_profile("ci", database=None, derandomize=True, print_blob=True)
settings.register_profile("explore", database=_EXAMPLES, derandomize=False, print_blob=True)
settings.load_profile(os.environ.get("DOORLOC_HYPOTHESIS_PROFILE", "dev"))


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture(scope="session")
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.fail(
            f"real data not found at {SHARED_DATA}: the repository must be cloned with shared/ beside it"
        )
    return SHARED_DATA


@pytest.fixture(scope="session")
def thesis_cell_path() -> Path:
    return REPO / "fixtures" / "cell_thesis.yaml"


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:  # noqa: ARG001 - pytest hook
    """Say which recipe-database backends ran (ids ``[sqlite]``/``[postgresql]``), so CI logs show both."""
    counts: dict[str, dict[str, int]] = {}
    for outcome in ("passed", "failed", "error", "skipped"):
        for rep in terminalreporter.stats.get(outcome, []):
            nodeid = getattr(rep, "nodeid", "")
            for backend in ("sqlite", "postgresql"):
                if f"[{backend}" in nodeid and getattr(rep, "when", "call") in ("call", "setup"):
                    if outcome == "passed" and rep.when != "call":
                        continue
                    counts.setdefault(backend, {}).setdefault(outcome, 0)
                    counts[backend][outcome] += 1
    if counts:
        parts = [
            f"{b}: " + ", ".join(f"{n} {o}" for o, n in sorted(c.items())) for b, c in sorted(counts.items())
        ]
        terminalreporter.write_line("recipe database backends -- " + "; ".join(parts))
