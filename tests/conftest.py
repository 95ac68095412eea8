"""Shared test helpers: where the repository and the real data live; Hypothesis profiles."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings
from hypothesis.database import DirectoryBasedExampleDatabase

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"

# Hypothesis profiles. A property test that fails saves its shrunk failing example in the example
# database (.hypothesis/examples/, git-ignored, shared by xdist workers); every later run replays the
# saved examples first, so a failure found once fails again until it is fixed, and the failure report
# carries a ``@reproduce_failure`` blob (print_blob) to pin it in the test itself.
# - "dev" (default): random exploration (derandomize off) + the database: new inputs on every run.
# - "ci": the same, so CI keeps looking for new failures; CI should keep .hypothesis/examples/ between
#   runs (cache it) so that what one run found the next one replays.
# - "deterministic": derandomized, no database: the exact same examples on every run and machine, for
#   bisecting or for a release gate that must not change verdict from run to run.
# Pick one with ``pytest --hypothesis-profile=NAME`` or DOORLOC_HYPOTHESIS_PROFILE=NAME.
# To try a property under many seeds in one go: ``python scripts/hypothesis_seeds.py tests/core/test_camera.py 200``.
_EXAMPLES = DirectoryBasedExampleDatabase(str(REPO / ".hypothesis" / "examples"))
settings.register_profile("dev", database=_EXAMPLES, derandomize=False, print_blob=True)
settings.register_profile("ci", database=_EXAMPLES, derandomize=False, print_blob=True)
settings.register_profile("deterministic", database=None, derandomize=True, print_blob=True)
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
