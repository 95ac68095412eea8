"""Shared test helpers: where the repository and the real data live."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture(scope="session")
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.fail(f"real data not found at {SHARED_DATA}: the repository must be cloned with shared/ beside it")
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
        parts = [f"{b}: " + ", ".join(f"{n} {o}" for o, n in sorted(c.items())) for b, c in sorted(counts.items())]
        terminalreporter.write_line("recipe database backends -- " + "; ".join(parts))
