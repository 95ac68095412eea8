"""CPU slots handed out round-robin among clients, so one client's queue cannot starve another's.

A plain FIFO limiter serves waiting requests in arrival order: a client that keeps its share of the queue full
puts all of its requests ahead of another client's one. :class:`FairSlots` keeps one FIFO per client and, when a
slot frees, hands it to the next client in turn; a client with one waiting request waits for at most one
request of each other client. A client (an API key) may stand for several members (the addresses using that
key): within a client the turn goes round its members the same way, so one member of a shared key cannot put
another's request behind all of its own. (No library offers this for anyio; it is a few dozen lines.)

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

from collections import deque

import anyio

__all__ = ["FairSlots"]


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
