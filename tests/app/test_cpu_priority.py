"""CPU priority as part of fairness: a client over its share of recent worker time waits for the slots of
lower-priority workers, so another client's job neither waits behind its job nor shares the CPU with it
equally; and the serving process runs below its workers, so many cheap refusals do not slow a locate."""

from __future__ import annotations

import os
import subprocess
import sys

import anyio
import numpy as np
import pytest

from doorloc.app.decodepool import DecodePool, lower_cpu_priority
from doorloc.app.fairslots import RecentUse
from doorloc.app.http.admission import release_cpu_slot, take_cpu_slot
from doorloc.app.http.metrics import ServiceMetrics
from doorloc.app.http.state import ServiceState

from .conftest import dev_settings, png_bytes

unix_only = pytest.mark.skipif(not hasattr(os, "setpriority"), reason="nice levels are Unix")


def test_recent_use_decays_and_names_only_the_client_over_its_share():
    now = [0.0]
    use = RecentUse(half_life_s=10.0, factor=1.0, clock=lambda: now[0])
    use.add("flood", 3.0)
    assert not use.over_share("flood")  # alone, however much it used
    assert use.over_share("flood", present=["line"])  # another client waits now: 3 s of 3 s
    assert not use.over_share("line", present=["flood"])
    use.add("line", 3.0)  # an equal share each: neither is over it
    assert not use.over_share("flood") and not use.over_share("line")
    use.add("line", 0.5)  # now the line used more than half: it goes second
    assert use.over_share("line") and not use.over_share("flood")
    now[0] = 10.0
    assert use.seconds("flood") == pytest.approx(1.5) and use.seconds("line") == pytest.approx(1.75)
    now[0] = 500.0  # both forgotten: neither is present any more
    assert not use.over_share("flood") and use.seconds("flood") < RecentUse.FORGET_S


def _state(**settings) -> ServiceState:
    # worker processes configured (none is started: load() would start them), one CPU slot
    base = {"locate_concurrency": 1, "max_queue": 7, "decode_in_threads": False}
    return ServiceState(dev_settings(**(base | settings)), ServiceMetrics())


def test_a_client_over_its_share_waits_for_the_lower_priority_slots_not_for_the_others():
    state = _state(over_share_nice=12)
    assert state.over_share is not None and state.over_share.nice == 12 and state.workers.nice == 0
    state.recent_use.add("key:flood", 5.0)
    state.recent_use.add("key:line", 0.05)

    async def script():
        flood = await take_cpu_slot(state, None, "key:flood", "a")
        line = await take_cpu_slot(state, None, "key:line", "b")  # at once: the flood holds the other slots
        got = []

        async def flood_again():
            got.append(await take_cpu_slot(state, None, "key:flood", "a"))

        async with anyio.create_task_group() as tg:
            tg.start_soon(flood_again)
            await anyio.sleep(0.05)
            waited = not got  # behind its own job, though the line's slot comes free first
            release_cpu_slot(state, "key:line", "b", line)
            await anyio.sleep(0.05)
            still_waited = not got
            release_cpu_slot(state, "key:flood", "a", flood)
        release_cpu_slot(state, "key:flood", "a", got[0])
        return flood, line, got[0], waited, still_waited

    flood, line, again, waited, still_waited = anyio.run(script)
    assert flood.over_share and not line.over_share and again.over_share
    assert waited and still_waited
    assert state.limiter.free == 1 and state.over_share_limiter is not None
    assert state.over_share_limiter.free == 1 and state.admitted == 0
    assert state.recent_use.seconds("key:line") > 0.05  # the time it held the slot counted


def test_a_client_with_nothing_else_in_flight_takes_an_idle_ordinary_slot_when_the_lower_ones_are_taken():
    """A steady client that had the service to itself when a flood arrived is the one over its share for a
    while; its images waited for the lower-priority slot while the ordinary one stood idle. With nothing else
    in flight it takes the idle ordinary slot; a client with another image in flight waits for its own kind."""
    state = _state(over_share_nice=12)
    state.recent_use.add("key:line", 5.0)
    state.recent_use.add("key:bulk", 5.0)
    state.recent_use.add("key:flood", 0.05)  # just arrived

    async def script():
        bulk = await take_cpu_slot(state, None, "key:bulk", "a")  # over its share: the lower slot
        line = await take_cpu_slot(state, None, "key:line", "b")  # over too, the lower slot taken: ordinary
        got = []

        async def bulk_again():
            got.append(await take_cpu_slot(state, None, "key:bulk", "c"))  # another in flight: below

        async with anyio.create_task_group() as tg:
            tg.start_soon(bulk_again)
            await anyio.sleep(0.05)
            release_cpu_slot(state, "key:line", "b", line)  # the ordinary slot idle again
            await anyio.sleep(0.05)
            waited = not got
            release_cpu_slot(state, "key:bulk", "a", bulk)
        release_cpu_slot(state, "key:bulk", "c", got[0])
        return bulk, line, got[0], waited

    bulk, line, again, waited = anyio.run(script)
    assert bulk.over_share and not line.over_share
    assert waited and again.over_share
    assert state.limiter.free == 1 and state.over_share_limiter.free == 1 and state.admitted == 0


def test_a_client_over_its_share_leaves_idle_ordinary_slots_to_the_others():
    """A job over its share that took an idle ordinary slot ran beside a steady client's image at the same
    priority, and a flood that took every ordinary slot between that client's images made each of them wait
    for a whole job. It waits for the lower-priority slots (as many as the ordinary ones) instead."""
    state = _state(over_share_nice=12, locate_concurrency=2)
    state.recent_use.add("key:flood", 5.0)
    state.recent_use.add("key:line", 0.05)
    assert state.over_share_limiter is not None

    async def script():
        lower = [await take_cpu_slot(state, None, "key:flood", a) for a in ("a", "c")]  # both lower slots
        got = []

        async def flood_again():
            got.append(await take_cpu_slot(state, None, "key:flood", "d"))  # another of its addresses

        async with anyio.create_task_group() as tg:
            tg.start_soon(flood_again)  # both ordinary slots idle, the lower ones taken: it waits
            await anyio.sleep(0.05)
            waited = not got
            lines = [await take_cpu_slot(state, None, "key:line", a) for a in ("b", "e")]  # both, at once
            release_cpu_slot(state, "key:flood", "a", lower[0])
        release_cpu_slot(state, "key:flood", "c", lower[1])
        release_cpu_slot(state, "key:flood", "d", got[0])
        for a, turn in zip(("b", "e"), lines, strict=True):
            release_cpu_slot(state, "key:line", a, turn)
        return lower, got[0], lines, waited

    lower, again, lines, waited = anyio.run(script)
    assert all(t.over_share for t in lower)
    assert waited and again.over_share and not any(t.over_share for t in lines)
    assert state.limiter.free == 2 and state.over_share_limiter.free == 2 and state.admitted == 0


def test_without_lower_priority_workers_every_job_takes_the_same_slots():
    state = _state(over_share_nice=0)
    assert state.over_share is None and state.over_share_limiter is None
    state.recent_use.add("key:flood", 5.0)

    async def script():
        flood = await take_cpu_slot(state, None, "key:flood", "a")
        with anyio.move_on_after(0.05):
            await take_cpu_slot(state, None, "key:line", "b")
            return flood, True
        release_cpu_slot(state, "key:flood", "a", flood)
        return flood, False

    flood, line_got_a_slot = anyio.run(script)
    assert not flood.over_share and not line_got_a_slot  # one slot, held by the flood


def _own_process(code: str) -> str:
    """What ``code`` prints, run in a Python process of its own (a priority lowered there stays there)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert out.returncode == 0, out.stderr
    return out.stdout


@unix_only
def test_lower_cpu_priority_lowers_every_thread_and_those_started_later():
    code = (
        "import os, threading\n"
        "from doorloc.app.decodepool import lower_cpu_priority\n"
        "e = threading.Event(); t = threading.Thread(target=e.wait); t.start()\n"
        "before = os.getpriority(os.PRIO_PROCESS, 0)\n"
        "assert lower_cpu_priority(4)\n"
        "tids = [int(x) for x in os.listdir('/proc/self/task')] if os.path.isdir('/proc/self/task') else [0]\n"
        "now = sorted({os.getpriority(os.PRIO_PROCESS, tid) for tid in tids})\n"
        "got = []; later = threading.Thread(target=lambda: got.append(os.getpriority(os.PRIO_PROCESS, 0)))\n"
        "later.start(); later.join(); e.set(); t.join()\n"
        "print(before, len(tids), now, got)\n"
    )
    before, threads, now, later = _own_process(code).split(" ", 3)
    want = min(int(before) + 4, 19)
    assert (now, later.strip()) == (f"[{want}]", f"[{want}]")
    assert sys.platform != "linux" or int(threads) >= 2  # the waiting thread was lowered too
    assert not lower_cpu_priority(0)  # nothing asked: nothing changed (this process stays as it is)


@unix_only
def test_a_service_lowers_its_process_once_however_many_it_holds():
    code = (
        "import os\n"
        "from doorloc.app.decodepool import nice_at_least\n"
        "before = os.getpriority(os.PRIO_PROCESS, 0)\n"
        "first = nice_at_least(before + 3)\n"
        "second = nice_at_least(before + 3)\n"
        "print(before, first, second, os.getpriority(os.PRIO_PROCESS, 0))\n"
    )
    before, first, second, after = _own_process(code).split()
    assert (first, second, int(after)) == ("True", "True", min(int(before) + 3, 19))


@unix_only
def test_a_pools_workers_run_at_its_nice_level_and_still_decode():
    # Workers start from the forkserver, which keeps the priority this process had when it started it (an
    # in-process service of an earlier test may have lowered this process since): a pool at nice 0 beside
    # it is the level the 6 are counted from.
    png = png_bytes(np.full((8, 8), 9, np.uint8))
    with (
        DecodePool(1, cpu_s=5, memory_bytes=200_000_000, nice=6) as pool,
        DecodePool(1, cpu_s=5, memory_bytes=200_000_000) as plain,
    ):
        assert pool.decode(png, "a.png", timeout_s=60).shape == (8, 8)
        assert plain.decode(png, "a.png", timeout_s=60).shape == (8, 8)
        (worker,), (plain_worker,) = pool._workers, plain._workers
        nice = os.getpriority(os.PRIO_PROCESS, worker.process.pid)
        base = os.getpriority(os.PRIO_PROCESS, plain_worker.process.pid)
    assert nice == min(base + 6, 19)
    assert base <= os.getpriority(os.PRIO_PROCESS, 0)  # never below the process that started the pool


def busy_locate(image, cell, door, *, image_name="", trace=None, jpeg_quality=0):
    """A stand-in locate that spends about 0.3 s of CPU on an image whose first pixel is 200."""
    import time

    from doorloc.vision.result import LocateResult

    if int(image[0, 0]) == 200:
        end = time.process_time() + 0.3
        while time.process_time() < end:
            pass
    return LocateResult.refusal(image_name, "no_door", "stand-in")


def test_the_jobs_worker_cpu_time_is_counted_not_the_time_its_slot_was_held():
    from .test_decodepool import _thesis_cell

    cell = _thesis_cell()
    busy, quiet = (png_bytes(np.full((6, 8), v, np.uint8)) for v in (200, 7))
    with DecodePool(1, cpu_s=5, memory_bytes=300_000_000, locate_fn=busy_locate, nice=2) as pool:
        got = [
            pool.decode_and_locate(
                data, "x.png", cell, cell.default_door, max_decoded_bytes=10**8, timeout_s=60
            )
            for data in (busy, quiet)
        ]
    assert got[0].worker_cpu_s >= 0.25 and got[1].worker_cpu_s < 0.1
    # and what the request cost, as its Server-Timing says it: the spin is the worker's locating, not its
    # decoding of the small PNG, and counts though this thread only waited for it
    cost = got[0].cpu_ms(0.0)
    assert 0.0 <= got[0].worker_decode_cpu_s < 0.1 and cost["locate"] >= 250.0, cost

    state = _state(over_share_nice=12)

    async def hold(cpu_s: float | None) -> None:
        turn = await take_cpu_slot(state, None, "key:line", "a")
        turn.worker_cpu_s = cpu_s
        await anyio.sleep(0.2)  # waiting behind others (on a busy CPU) is not use
        release_cpu_slot(state, "key:line", "a", turn)

    anyio.run(hold, 0.01)
    assert state.recent_use.seconds("key:line") == pytest.approx(0.01, abs=0.002)
    anyio.run(hold, None)  # a job refused or stopped: the time held counts
    assert state.recent_use.seconds("key:line") >= 0.2


def _descendants(pid: int) -> list[int]:
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        for tid in os.listdir(f"/proc/{p}/task"):
            with open(f"/proc/{p}/task/{tid}/children") as f:
                kids = [int(c) for c in f.read().split()]
            found += kids
            todo += kids
    return found


@pytest.mark.skipif(not os.path.exists(f"/proc/self/task/{os.getpid()}/children"), reason="Linux /proc")
def test_serve_runs_below_its_workers_and_its_over_share_workers_below_both(start_serve, tmp_path):
    env = {"DOORLOC_SERVE_NICE": "3", "DOORLOC_OVER_SHARE_NICE": "9", "DOORLOC_LOCATE_CONCURRENCY": "1"}
    base, proc = start_serve(tmp_path, "--open", "--create-database", env=env)
    own = os.getpriority(os.PRIO_PROCESS, 0)
    serving = {os.getpriority(os.PRIO_PROCESS, int(t)) for t in os.listdir(f"/proc/{proc.pid}/task")}
    others = sorted(os.getpriority(os.PRIO_PROCESS, p) for p in _descendants(proc.pid))
    assert serving == {min(own + 3, 19)}
    # the forkserver, the resource tracker and the locating worker as they were; one worker 9 levels lower
    assert others.count(min(own + 9, 19)) == 1 and others.count(own) == len(others) - 1 >= 3

    import httpx

    small = png_bytes(np.full((48, 64), 130, np.uint8))
    r = httpx.post(f"{base}/v1/locate", files={"image": ("s.png", small, "image/png")}, timeout=60)
    assert r.status_code in (200, 422), r.text  # located in the worker (or refused), never a 500
