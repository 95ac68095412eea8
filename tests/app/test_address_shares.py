"""Inside one API key's share of a worker's queue, each client address (after trusted proxies) has a share of
its own: one machine of a shared key cannot take all of the key's places."""

from __future__ import annotations

import anyio
import pytest

from doorloc.app.http.admission import release_cpu_slot, shedding_problem, take_cpu_slot
from doorloc.app.http.metrics import ServiceMetrics
from doorloc.app.http.problems import ProblemError
from doorloc.app.http.state import ServiceState

from .conftest import dev_settings


def _state(**settings) -> ServiceState:
    base = {"locate_concurrency": 1, "max_queue": 7, "decode_in_threads": True}
    return ServiceState(dev_settings(**(base | settings)), ServiceMetrics(), locate_fn=lambda *a, **k: None)


def test_one_address_fills_only_its_share_of_its_keys_places():
    state = _state()
    assert (state.per_client_limit, state.per_address_limit) == (4, 2)

    async def flood_then_other():
        # the first takes the CPU slot, the second waits in the queue: the address's share is then full
        await take_cpu_slot(state, None, "key:line", "10.0.0.5")
        async with anyio.create_task_group() as tg:
            tg.start_soon(take_cpu_slot, state, None, "key:line", "10.0.0.5")
            await anyio.sleep(0.01)
            refused = shedding_problem(state, "key:line", "10.0.0.5")
            other = shedding_problem(state, "key:line", "10.0.0.6")
            another_key = shedding_problem(state, "key:office", "10.0.0.5")
            release_cpu_slot(state, "key:line", "10.0.0.5")  # the waiting one gets the slot
        release_cpu_slot(state, "key:line", "10.0.0.5")
        return refused, other, another_key

    refused, other, another_key = anyio.run(flood_then_other)
    assert isinstance(refused, ProblemError) and refused.status == 503 and "address" in refused.detail
    assert other is None and another_key is None
    assert state.admitted == 0 and state.address_admitted == {} and state.client_admitted == {}


def test_the_keys_share_still_bounds_all_its_addresses():
    state = _state(max_per_address=3)

    async def script():
        await take_cpu_slot(state, None, "key:line", "a")
        async with anyio.create_task_group() as tg:
            for address in ("a", "b", "b"):
                tg.start_soon(take_cpu_slot, state, None, "key:line", address)
            await anyio.sleep(0.01)
            full = shedding_problem(state, "key:line", "c")  # 4 held: the key's share
            for address in ("a", "a", "b", "b"):
                release_cpu_slot(state, "key:line", address)
                await anyio.sleep(0.001)
        return full

    full = anyio.run(script)
    assert full is not None and "its share of this worker" in full.detail
    assert state.admitted == 0


@pytest.mark.parametrize("settings", [{}, {"api_key": None}])
def test_an_open_service_has_no_address_shares(settings):
    state = _state(**settings)
    assert shedding_problem(state, "", "127.0.0.1") is None
