"""CPU slots handed out round-robin among clients, so one client's queue cannot starve another's.

A plain FIFO limiter serves waiting requests in arrival order: a client that keeps its share of the queue full
puts all of its requests ahead of another client's one. :class:`FairSlots` keeps one FIFO per client and, when a
slot frees, hands it to the next client in turn; a client with one waiting request waits for at most one
request of each other client. A client (an API key) may stand for several members (the addresses using that
key): within a client the turn goes round its members the same way, so one member of a shared key cannot put
another's request behind all of its own. (No library offers this for anyio; it is a few dozen lines.)

Turns alone cannot stop a client that always has a job running from slowing another's: the other's job still
waits for the running one, and on a busy CPU the two share it equally. :class:`RecentUse` keeps each client's
recent worker time, so that the service can run the jobs of a client using more than its share in worker
processes of lower CPU priority (their own slots), where another client's job overtakes them on the CPU.

Examples
--------
>>> import anyio
>>> async def demo():
...     slots = FairSlots(1)
...     await slots.acquire("a")
...     order = []
...     async def wait(client, tag):
...         await slots.acquire(client)
...         order.append(tag)
...         slots.release()
...     async with anyio.create_task_group() as tg:
...         for tag in ("a1", "a2", "a3"):
...             tg.start_soon(wait, "a", tag)
...             await anyio.sleep(0.01)
...         tg.start_soon(wait, "b", "b1")
...         await anyio.sleep(0.01)
...         slots.release()
...     return order
>>> anyio.run(demo)
['a1', 'b1', 'a2', 'a3']
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable

import anyio

__all__ = ["FairSlots", "RecentUse"]


class _Waiter:
    __slots__ = ("event", "granted")

    def __init__(self) -> None:
        self.event = anyio.Event()
        self.granted = False


class FairSlots:
    """``slots`` tokens; waiting acquirers are served one client at a time in turn, and within a client one
    member at a time in turn (event-loop use only)."""

    def __init__(self, slots: int) -> None:
        self.free = slots
        #: waiting requests per client and member; dict order is the turn order (a served one moves to the end)
        self._waiting: dict[str, dict[str, deque[_Waiter]]] = {}

    @property
    def waiting(self) -> int:
        return sum(len(q) for members in self._waiting.values() for q in members.values())

    async def acquire(self, client: str, member: str = "") -> None:
        """Wait for a slot (cancellable: a cancelled wait gives back a slot it was handed)."""
        if self.free > 0 and not self._waiting:
            self.free -= 1
            return
        waiter = _Waiter()
        self._waiting.setdefault(client, {}).setdefault(member, deque()).append(waiter)
        try:
            await waiter.event.wait()
        except BaseException:
            if waiter.granted:
                self.release()
            else:
                members = self._waiting.get(client, {})
                queue = members.get(member)
                if queue is not None and waiter in queue:
                    queue.remove(waiter)
                    if not queue:
                        del members[member]
                    if not members:
                        del self._waiting[client]
            raise

    def release(self) -> None:
        """Give a slot back: to the next waiting client (and its next member) in turn, else to the free pool."""
        if not self._waiting:
            self.free += 1
            return
        client = next(iter(self._waiting))
        members = self._waiting.pop(client)
        member = next(iter(members))
        queue = members.pop(member)
        waiter = queue.popleft()
        if queue:
            members[member] = queue  # to the end of the client's turn
        if members:
            self._waiting[client] = members  # to the end of the turn
        waiter.granted = True
        waiter.event.set()


class RecentUse:
    """Seconds of worker time per client, each decaying by half every ``half_life_s`` seconds.

    A client is *over its share* when its recent time is more than ``factor`` times an equal share of all
    present clients' (those with recent time, and those named as waiting): with the default factor 1, more
    than half of the total with two clients, a third with three. A client alone is never over its share,
    however much it uses. (A factor of 1 rather than more: a client that always has a job waiting, served
    in turn with a client that sends one image at a time, takes a little over half of the worker time, not
    more; the client that used less recently is the one to go first, as in the kernel's own fair scheduler.)

    Examples
    --------
    >>> now = [0.0]
    >>> use = RecentUse(half_life_s=10.0, clock=lambda: now[0])
    >>> use.add("a", 2.0); use.add("b", 1.9)
    >>> use.over_share("a"), use.over_share("b")
    (True, False)
    >>> alone = RecentUse(); alone.add("a", 5.0); alone.over_share("a")
    False
    >>> now[0] = 10.0; round(use.seconds("a"), 3)
    1.0
    """

    #: recent time below this (seconds) is forgotten: the client is no longer present
    FORGET_S = 1e-3

    def __init__(
        self, half_life_s: float = 5.0, factor: float = 1.0, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.half_life_s = half_life_s
        self.factor = factor
        self._clock = clock
        #: client -> (seconds, when they were last decayed)
        self._use: dict[str, tuple[float, float]] = {}

    def seconds(self, client: str) -> float:
        """``client``'s recent worker time, seconds (decayed to now)."""
        seconds, at = self._use.get(client, (0.0, 0.0))
        return seconds * 0.5 ** ((self._clock() - at) / self.half_life_s)

    def add(self, client: str, seconds: float) -> None:
        """Count ``seconds`` of worker time (a job just done) for ``client``."""
        self._use[client] = (self.seconds(client) + max(seconds, 0.0), self._clock())

    def over_share(self, client: str, present: Iterable[str] = ()) -> bool:
        """Whether ``client`` used more than ``factor`` times its equal share recently (``present``: clients
        waiting now, counted even before they have any recent time)."""
        recent = {c: self.seconds(c) for c in list(self._use)}
        for c, s in recent.items():
            if s < self.FORGET_S:
                del self._use[c]
        clients = {c for c, s in recent.items() if s >= self.FORGET_S} | set(present) | {client}
        if len(clients) < 2:
            return False
        total = sum(recent.get(c, 0.0) for c in clients)
        return recent.get(client, 0.0) > self.factor * total / len(clients)
