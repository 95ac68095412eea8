"""Recipe tests run on SQLite always and on PostgreSQL when DOORLOC_TEST_POSTGRES_URL is set.

Tests that take the ``db_url`` fixture get ids ``[sqlite]`` and ``[postgresql]`` so the log shows which
backends ran. Each PostgreSQL test gets its own schema (``search_path``), dropped afterwards, so
pytest-xdist workers never see each other's tables. With ``DOORLOC_CI=1`` a missing PostgreSQL URL
fails the PostgreSQL tests instead of skipping them: CI must not lose them silently.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url

from doorloc.recipes.models import DoorRecipe, Hinge, PointCorrection

PG_ENV = "DOORLOC_TEST_POSTGRES_URL"
GOLDEN_DIR = Path(__file__).with_name("golden")


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def db_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """A URL of an empty database of the parametrized backend."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'recipes.db'}"
        return
    base = os.environ.get(PG_ENV)
    if not base:
        if os.environ.get("DOORLOC_CI") == "1":
            pytest.fail(
                f"DOORLOC_CI=1 but {PG_ENV} is not set: scripts/ci/postgres.sh must start PostgreSQL "
                "so the recipe tests run on it"
            )
        pytest.skip(f"no PostgreSQL server: set {PG_ENV}=postgresql+psycopg://user:pw@host/db to run these")
    schema = f"t_{uuid.uuid4().hex[:16]}"
    admin = create_engine(base)
    with admin.begin() as conn:
        conn.execute(text(f'CREATE SCHEMA "{schema}"'))
    url = make_url(base).update_query_dict({"options": f"-csearch_path={schema}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with admin.begin() as conn:
            conn.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


@pytest.fixture
def store(db_url: str):
    from doorloc.recipes.store import RecipeStore

    with RecipeStore(db_url) as s:
        yield s


def make_recipe(door_id: str = "D-100", **over) -> DoorRecipe:
    """A valid two-hinge recipe (6-point and 9-point with corrections); keyword overrides."""
    hinges = over.pop("hinges", None) or [
        Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3.5, corner_radius_mm=8),
        Hinge(
            z_mm=1750,
            length_mm=110,
            width_mm=28,
            x_mm=12,
            depth_mm=3.2,
            corner_radius_mm=10,
            path_points=9,
            corrections=[PointCorrection(dx_mm=0.01 * k, dy_mm=0.02, dz_mm=0.1 + 0.01 * k) for k in range(9)],
        ),
    ]
    data = dict(
        door_id=door_id,
        width_mm=900,
        height_mm=2100,
        thickness_mm=50,
        arris_mm=1.0,
        hinges=hinges,
        tool_diameter_mm=16,
        spindle_rpm=18000,
        feed_mm_s=25,
    )
    data.update(over)
    return DoorRecipe(**data)


@pytest.fixture
def recipe_factory():
    """:func:`make_recipe`, for tests (conftest modules are not importable under --import-mode=importlib)."""
    return make_recipe
