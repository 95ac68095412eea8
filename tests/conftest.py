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
