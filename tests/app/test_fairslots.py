"""CPU slots in turn among clients: one client's full queue does not put another client's request behind it."""

from __future__ import annotations

import anyio
import pytest

from doorloc.app.fairslots import FairSlots


def _run(script):
    return anyio.run(script)


def test_a_second_client_is_served_after_one_request_of_the_first():
    async def script():
        slots, order = FairSlots(1), []
        await slots.acquire("flood")

        async def one(client, tag):
            await slots.acquire(client)
            order.append(tag)
            slots.release()

        async with anyio.create_task_group() as tg:
            for k in range(5):
                tg.start_soon(one, "flood", f"f{k}")
                await anyio.sleep(0.005)
            tg.start_soon(one, "panel", "p")
            await anyio.sleep(0.005)
            slots.release()
        return order

    assert _run(script) == ["f0", "p", "f1", "f2", "f3", "f4"]


def test_a_cancelled_wait_gives_its_slot_back():
    async def script():
        slots = FairSlots(1)
        await slots.acquire("a")
        with anyio.move_on_after(0.01):
            await slots.acquire("b")  # times out while waiting
        assert slots.waiting == 0
        slots.release()
        with anyio.fail_after(1):
            await slots.acquire("c")  # the slot is free again
        return slots.free

    assert _run(script) == 0


@pytest.mark.parametrize("n", [1, 3])
def test_slots_are_never_handed_out_twice(n):
    async def script():
        slots, running, peak = FairSlots(n), [0], [0]

        async def work(client):
            await slots.acquire(client)
            running[0] += 1
            peak[0] = max(peak[0], running[0])
            await anyio.sleep(0.001)
            running[0] -= 1
            slots.release()

        async with anyio.create_task_group() as tg:
            for k in range(40):
                tg.start_soon(work, f"c{k % 4}")
        return peak[0], slots.free

    assert _run(script) == (n, n)


def test_within_a_shared_key_each_address_gets_its_turn():
    """One machine flooding with a shared key does not put another machine's request (same key) behind all of
    its own; other keys keep their turn among the keys."""

    async def script():
        slots, order = FairSlots(1), []
        await slots.acquire("key:line", "10.0.0.5")

        async def one(client, member, tag):
            await slots.acquire(client, member)
            order.append(tag)
            slots.release()

        async with anyio.create_task_group() as tg:
            for k in range(4):
                tg.start_soon(one, "key:line", "10.0.0.5", f"flood{k}")
                await anyio.sleep(0.005)
            tg.start_soon(one, "key:line", "10.0.0.6", "panel")
            await anyio.sleep(0.005)
            tg.start_soon(one, "key:office", "10.0.1.1", "office")
            await anyio.sleep(0.005)
            slots.release()
        return order

    # keys in turn (line, office, line, ...), and within the line's key its two addresses in turn
    assert _run(script) == ["flood0", "office", "panel", "flood1", "flood2", "flood3"]
