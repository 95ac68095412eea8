"""Schemathesis against the in-process app: every check, no 5xx, no undocumented status, no schema violation."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from schemathesis.config import SchemathesisConfig
from schemathesis.generation import GenerationMode

from doorloc.app.http import create_app
from doorloc.app.settings import ServiceSettings
from doorloc.cell import load_cell
from doorloc.recipes.store import RecipeStore

# one test process starts the service (its worker processes take seconds) for all the module's tests
pytestmark = pytest.mark.xdist_group("api_schema")

CELL = load_cell(Path(__file__).resolve().parents[2] / "fixtures" / "cell_thesis.yaml")
# The real pipeline: schemathesis's images are mostly not images at all, and those that decode are refused fast.
API_KEY = "schemathesis-key"
APP = create_app(
    # schemathesis sends hundreds of wrong keys from one address: no wrong-key budget here (429 is documented),
    # and their answers do not wait (the wait is held by test_access)
    ServiceSettings(
        max_upload_bytes=2_000_000,
        api_key=API_KEY,
        allowed_hosts=["*"],
        auth_failures_per_minute=1_000_000,
        auth_refusal_delay_s=0,
    ),
    cell=CELL,
    store=RecipeStore("sqlite://"),
)


class _RequestsOnly:
    """``APP`` for schemathesis without its lifespan: schemathesis's pytest plugin ends an ASGI app's
    lifespan after every test, and ``APP``'s start-up (its locate and decode worker processes, ~5 s) then
    ran once per test. The service runs once for the module instead (:func:`_service_running`), as a server
    runs it; every request still goes to ``APP`` itself."""

    def __init__(self, app) -> None:
        self.app = app

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "lifespan":
            await self.app(scope, receive, send)
            return
        while True:
            message = await receive()
            if message["type"] == "lifespan.startup":
                await send({"type": "lifespan.startup.complete"})
            elif message["type"] == "lifespan.shutdown":
                await send({"type": "lifespan.shutdown.complete"})
                return


@pytest.fixture(scope="module", autouse=True)
def _service_running():
    """``APP``'s own lifespan (the cell, the store, the worker processes), once for the module's tests."""
    with TestClient(APP):
        yield


# All checks run. With the key configured, the auth checks (ignored_auth, missing_required_header) test
# that requests without it get 401. One check needs telling what "valid" means where JSON Schema cannot say it:
# positive_data_acceptance sees an upload the schema calls valid (any bytes) answered 415/422 when the bytes
# are not a decodable image, and a recipe answered 422 when it breaks a cross-field rule (hinge outside the
# door, tool larger than the corner...). Those answers are the contract, so they are expected there.
CONFIG = SchemathesisConfig.from_dict(
    {
        "headers": {"X-API-Key": API_KEY},
        "operations": [
            {
                "include-path": "/v1/locate",
                "checks": {"positive_data_acceptance": {"expected-statuses": ["2xx", "401", "415", "422"]}},
            },
            {
                "include-path": "/v1/doors/{door_id}",  # GET, PUT, DELETE: 404 is the default's unknown door
                "checks": {"positive_data_acceptance": {"expected-statuses": ["2xx", "401", "404", "422"]}},
            },
            {
                "include-path": "/v1/doors/{door_id}/history",
                "checks": {"positive_data_acceptance": {"expected-statuses": ["2xx", "401", "404", "422"]}},
            },
        ],
    }
)
schema = schemathesis.openapi.from_asgi("/openapi.json", _RequestsOnly(APP), config=CONFIG)
#: examples per operation and mode; bench/bench_service_schema.py raises it
EXAMPLES = int(os.environ.get("DOORLOC_SCHEMATHESIS_EXAMPLES", "40"))
OPERATIONS = {result.ok().label: result.ok() for result in schema.get_all_operations()}


def _has_inputs(label: str) -> bool:
    raw = OPERATIONS[label].definition.raw
    return bool(raw.get("parameters") or raw.get("requestBody"))


# One pytest item per operation and mode, with both in the id. (schemathesis's own @schema.parametrize gives
# every item the same node id under pytest 9, and pytest-xdist then runs only one of them.) Negative cases
# (schema-violating requests) exist only for operations that take parameters or a body.
CASES = [(label, GenerationMode.POSITIVE) for label in sorted(OPERATIONS)] + [
    (label, GenerationMode.NEGATIVE) for label in sorted(OPERATIONS) if _has_inputs(label)
]


@pytest.mark.parametrize(("label", "mode"), CASES, ids=[f"{m.value}-{lab}" for lab, m in CASES])
def test_api_conforms_to_its_schema(label, mode):
    operation = OPERATIONS[label]

    @given(case=operation.as_strategy(generation_mode=mode))
    @settings(
        max_examples=EXAMPLES,
        deadline=None,
        suppress_health_check=list(HealthCheck),
        derandomize=True,
        database=None,
    )
    def check(case):
        case.call_and_validate()

    check()


def test_every_operation_is_tested():
    assert set(OPERATIONS) == {
        "GET /healthz",
        "GET /readyz",
        "GET /metrics",
        "GET /v1/cell",
        "POST /v1/locate",
        "GET /v1/doors",
        "GET /v1/doors/{door_id}",
        "PUT /v1/doors/{door_id}",
        "DELETE /v1/doors/{door_id}",
        "GET /v1/doors/{door_id}/history",
    }
