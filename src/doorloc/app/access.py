"""Who may call the HTTP service: API keys with roles, stored hashed in the recipe database.

Roles (each key has one):

- ``operator``: locate doors, read recipes, their history and the cell in use;
- ``engineer``: everything an operator may, plus change, retire or delete recipes, and read ``/metrics``;
- ``metrics``: ``/metrics`` only (for the monitoring scraper).

A key reads ``dlk_<key_id>_<secret>``. ``key_id`` is public and finds the key's row; of the secret only
a salted scrypt hash is kept (:func:`hashlib.scrypt`, the standard library's memory-hard KDF), so the
database leaking does not leak usable keys. A presented key is checked by deriving its hash again and
comparing the two hashes with :func:`hmac.compare_digest`. Deriving costs ~10-50 ms, so each
:class:`KeyStore` remembers which presented secrets it has already verified (a SHA-256 of them, compared
in constant time too); revocation is still seen at once because the row is read on every request.

A service demands a key for every ``/v1`` request and ``/metrics``. Only ``doorloc serve --open`` on a
loopback address, with no key in the database, answers without one (development use); once it has seen a
key it stays closed, even when every key is revoked. An unknown key id costs the same scrypt derivation as
a wrong secret for a known one, and each client address may send only so many wrong keys a minute
(:class:`FailureBudget`).

Examples
--------
>>> from doorloc.recipes.store import RecipeStore
>>> keys = KeyStore(RecipeStore("sqlite://").engine)
>>> keys.any_active()
False
>>> created = keys.create("line-1 panel", Role.operator)
>>> keys.authenticate(created.secret).role
<Role.operator: 'operator'>
>>> keys.authenticate("dlk_nope_nope") is None
True
"""

from __future__ import annotations

import builtins
import hashlib
import hmac
import re
import secrets
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import StrEnum

from sqlalchemy import Engine, insert, select, update

from doorloc.app.decodepool import lower_cpu_priority
from doorloc.recipes.tables import ApiKeyRow

__all__ = [
    "Role",
    "Principal",
    "CreatedKey",
    "KeyInfo",
    "KeyStore",
    "AccessKeyError",
    "role_allows",
    "LEGACY_KEY_NAME",
    "ANY_ACTIVE_TTL_S",
    "FailureBudget",
    "is_loopback",
]

#: scrypt cost: 2**14 x 8 x 128 B = 16 MiB and ~10-50 ms per derivation (the interactive-login setting of RFC 7914)
_SCRYPT = {"n": 2**14, "r": 8, "p": 1, "dklen": 32, "maxmem": 64 * 1024 * 1024}
_KEY_FORMAT = re.compile(r"^dlk_([0-9a-f]{12})_([A-Za-z0-9_-]{20,100})$")
_NAME_FORMAT = re.compile(r"^[A-Za-z0-9][A-Za-z0-9 ._:@/-]{0,63}$")
#: scrypt derivations one KeyStore runs at once (memory: this x 16 MiB)
_PARALLEL_DERIVATIONS = 2
#: verified secrets remembered per KeyStore (bounded: a flood of distinct keys cannot grow memory)
_CACHE_SIZE = 1024
#: how long "are there any keys at all?" is remembered: an open (keyless) service starts demanding keys at most
#: this long after the first one is created; revocation is not delayed (every presented key's row is read)
ANY_ACTIVE_TTL_S = 2.0
#: the name requests carry when they used the legacy single key (DOORLOC_API_KEY)
LEGACY_KEY_NAME = "DOORLOC_API_KEY"


class Role(StrEnum):
    operator = "operator"
    engineer = "engineer"
    metrics = "metrics"


#: what each role may do beyond itself: an engineer may do everything an operator or a scraper may
_IMPLIES: dict[Role, frozenset[Role]] = {
    Role.operator: frozenset({Role.operator}),
    Role.engineer: frozenset({Role.engineer, Role.operator, Role.metrics}),
    Role.metrics: frozenset({Role.metrics}),
}


def role_allows(held: Role, needed: Role) -> bool:
    """True when a key with role ``held`` may call an endpoint that needs ``needed``."""
    return needed in _IMPLIES[held]


class AccessKeyError(ValueError):
    """A key cannot be created or revoked (bad name, unknown key); the message says what to do."""


@dataclass(frozen=True)
class Principal:
    """Who made a request: the key's name and role (``anonymous`` when the service is open)."""

    name: str
    role: Role
    key_id: str | None = None


@dataclass(frozen=True)
class CreatedKey:
    """A new key: ``secret`` is shown once and never stored."""

    key_id: str
    name: str
    role: Role
    secret: str


@dataclass(frozen=True)
class KeyInfo:
    """One line of ``doorloc keys list`` (never the secret)."""

    key_id: str
    name: str
    role: Role
    created_at: datetime | None
    revoked_at: datetime | None


def _derive(secret: str, salt: bytes) -> bytes:
    return hashlib.scrypt(secret.encode(), salt=salt, **_SCRYPT)


def _lower_thread_priority(levels: int) -> None:
    """Lower the calling thread's CPU priority by ``levels`` nice levels (Linux only, where nice is a
    property of each thread; elsewhere it would lower the whole process, so nothing is done there).

    A flood of wrong keys costs one scrypt derivation each (it releases the GIL and runs beside the event
    loop); at a lower priority than the event loop, the service's other answers keep the CPU meanwhile."""
    if sys.platform.startswith("linux"):
        lower_cpu_priority(levels, every_thread=False)  # a sandbox may refuse: then it runs as before


_DUMMY_SALT = bytes(16)
_DUMMY_HASH = bytes(32)


class KeyStore:
    """API keys in the recipe database (table ``api_keys``, Alembic revision 0002).

    Parameters
    ----------
    engine : sqlalchemy.Engine
        The recipe database's engine (``RecipeStore.engine``), already migrated.
    """

    def __init__(self, engine: Engine, derivation_nice: int = 0) -> None:
        self.engine = engine
        self._verified: dict[str, bytes] = {}
        self._lock = threading.Lock()
        self._any_active: tuple[float, bool] | None = None  # (monotonic time, answer)
        # scrypt takes 16 MiB and ~10-50 ms: derivations run on this many threads of their own, so a flood of
        # wrong keys neither runs one per request thread nor leaves a freed 16 MiB in every thread's malloc arena
        self._derivations = ThreadPoolExecutor(
            _PARALLEL_DERIVATIONS,
            thread_name_prefix="doorloc-scrypt",
            initializer=_lower_thread_priority,
            initargs=(derivation_nice,),
        )

    def create(self, name: str, role: Role | str) -> CreatedKey:
        """Make a key for ``name`` with ``role``; its secret is in the answer and nowhere else."""
        role = Role(role)
        if not _NAME_FORMAT.match(name):
            raise AccessKeyError(
                f"key name {name!r} must be 1-64 letters, digits, spaces or ._:@/- and start with a "
                "letter or digit (name the person or machine that holds it)"
            )
        key_id = secrets.token_hex(6)
        secret = f"dlk_{key_id}_{secrets.token_urlsafe(32)}"
        salt = secrets.token_bytes(16)
        with self.engine.begin() as conn:
            self._any_active = None
            conn.execute(
                insert(ApiKeyRow).values(
                    key_id=key_id,
                    name=name,
                    role=role.value,
                    salt=salt.hex(),
                    key_hash=_derive(secret, salt).hex(),
                )
            )
        return CreatedKey(key_id, name, role, secret)

    def list(self) -> builtins.list[KeyInfo]:
        """Every key, revoked ones included, oldest first."""
        with self.engine.connect() as conn:
            rows = conn.execute(
                select(
                    ApiKeyRow.key_id,
                    ApiKeyRow.name,
                    ApiKeyRow.role,
                    ApiKeyRow.created_at,
                    ApiKeyRow.revoked_at,
                ).order_by(ApiKeyRow.id)
            )
            return [KeyInfo(r.key_id, r.name, Role(r.role), r.created_at, r.revoked_at) for r in rows]

    def revoke(self, name_or_id: str) -> builtins.list[str]:
        """Revoke the active keys named ``name_or_id`` (or the one with that key id); their key ids.

        Raises AccessKeyError when no active key matches.
        """
        with self.engine.begin() as conn:
            ids = list(
                conn.scalars(
                    select(ApiKeyRow.key_id).where(
                        ((ApiKeyRow.name == name_or_id) | (ApiKeyRow.key_id == name_or_id))
                        & ApiKeyRow.revoked_at.is_(None)
                    )
                )
            )
            if not ids:
                raise AccessKeyError(f"no active key named {name_or_id!r}; see doorloc keys list")
            conn.execute(
                update(ApiKeyRow).where(ApiKeyRow.key_id.in_(ids)).values(revoked_at=datetime.now(UTC))
            )
            self._any_active = None
        with self._lock:
            for i in ids:
                self._verified.pop(i, None)
        return ids

    def any_active(self, max_age_s: float = 0.0, remember: bool = True) -> bool:
        """True when at least one key is not revoked (the service then demands a key).

        ``max_age_s`` > 0 accepts an answer read that recently (the service asks on every keyless request);
        ``remember=False`` reads the database without keeping the answer for later calls.
        """
        now = time.monotonic()
        known = self.cached_any_active(max_age_s)
        if known is not None:
            return known
        with self.engine.connect() as conn:
            answer = (
                conn.scalar(select(ApiKeyRow.id).where(ApiKeyRow.revoked_at.is_(None)).limit(1)) is not None
            )
        if remember:
            self._any_active = (now, answer)
        return answer

    def cached_any_active(self, max_age_s: float) -> bool | None:
        """The remembered :meth:`any_active` answer when at most ``max_age_s`` old, else None (no I/O)."""
        cached = self._any_active
        if cached is not None and time.monotonic() - cached[0] <= max_age_s:
            return cached[1]
        return None

    def authenticate(self, presented: str, verified_only: bool = False) -> Principal | None:
        """The key's holder, or None when ``presented`` is not an active key.

        ``verified_only``: accept only a key already verified (no scrypt derivation): what a client over its
        wrong-key budget may still use, so that guessing from an address does not lock out its valid keys.
        """
        m = _KEY_FORMAT.match(presented)
        if m is None:
            return None
        key_id = m.group(1)
        with self.engine.connect() as conn:
            row = conn.execute(
                select(ApiKeyRow.name, ApiKeyRow.role, ApiKeyRow.salt, ApiKeyRow.key_hash).where(
                    (ApiKeyRow.key_id == key_id) & ApiKeyRow.revoked_at.is_(None)
                )
            ).one_or_none()
        if row is None:
            if verified_only:
                return None
            # derive anyway, from a dummy salt: an unknown id then costs what a known one with a wrong secret
            # does, so the answer's timing does not say which key ids exist
            hmac.compare_digest(
                self._derivations.submit(_derive, presented, _DUMMY_SALT).result(), _DUMMY_HASH
            )
            return None
        fingerprint = hashlib.sha256(presented.encode()).digest()
        with self._lock:
            known = self._verified.get(key_id)
        if known is not None and hmac.compare_digest(known, fingerprint):
            return Principal(row.name, Role(row.role), key_id)
        if verified_only:
            return None
        derived = self._derivations.submit(_derive, presented, bytes.fromhex(row.salt)).result()
        if not hmac.compare_digest(derived, bytes.fromhex(row.key_hash)):
            return None
        with self._lock:
            if len(self._verified) >= _CACHE_SIZE:
                self._verified.pop(next(iter(self._verified)))
            self._verified[key_id] = fingerprint
        return Principal(row.name, Role(row.role), key_id)


class FailureBudget:
    """Wrong keys each client address may send per minute (a sliding window), so guessing keys is slow.

    Bounded memory: at most ``max_clients`` addresses are remembered (the oldest forgotten first). Not
    thread-safe; the service calls it from its event loop only.

    Examples
    --------
    >>> b = FailureBudget(2, clock=lambda: 100.0)
    >>> b.record("10.0.0.9"); b.record("10.0.0.9"); b.retry_after("10.0.0.9")
    60
    >>> b.retry_after("10.0.0.7") is None
    True
    """

    #: keys an address over its budget may still have checked a minute, each key once: a client behind the
    #: same NAT or proxy as another that keeps sending a wrong key (a stale one in its settings), whose key
    #: this worker has not verified yet (after a restart; each worker of a service has its own), is then not
    #: refused for the whole minute
    TRIALS_PER_MINUTE = 3

    def __init__(self, per_minute: int, max_clients: int = 4096, clock=time.monotonic) -> None:  # noqa: ANN001
        self.per_minute = per_minute
        self.max_clients = max_clients
        self._clock = clock
        self._failures: dict[str, list[float]] = {}
        #: address -> {digest of a key tried over budget: when}
        self._trials: dict[str, dict[bytes, float]] = {}

    def _recent(self, client: str) -> list[float]:
        now = self._clock()
        times = [t for t in self._failures.get(client, ()) if now - t < 60.0]
        if times:
            self._failures[client] = times
        else:
            self._failures.pop(client, None)
        return times

    def retry_after(self, client: str) -> int | None:
        """Seconds until ``client`` may try a key again, or None when it is within its budget."""
        times = self._recent(client)
        if len(times) < self.per_minute:
            return None
        return max(1, int(60.0 - (self._clock() - times[-self.per_minute])) + 1)

    def may_try(self, client: str, presented: str) -> bool:
        """Whether ``presented`` (a key as sent) may still be checked from ``client`` although it is over its
        budget: each key once a minute, at most :attr:`TRIALS_PER_MINUTE` keys a minute (a trial that fails is
        a wrong key like any other). A key sent again and again is checked once a minute, however often."""
        now = self._clock()
        digest = hashlib.sha256(presented.encode()).digest()  # the keys themselves are not kept
        tried = {k: t for k, t in self._trials.get(client, {}).items() if now - t < 60.0}
        if digest in tried or len(tried) >= self.TRIALS_PER_MINUTE:
            self._trials[client] = tried
            return False
        if client not in self._trials and len(self._trials) >= self.max_clients:
            self._trials.pop(next(iter(self._trials)))
        tried[digest] = now
        self._trials[client] = tried
        return True

    def record(self, client: str) -> None:
        """Count one wrong key from ``client``."""
        times = self._recent(client)
        if not times and len(self._failures) >= self.max_clients:
            self._failures.pop(next(iter(self._failures)))
        self._failures[client] = [*times, self._clock()][-self.per_minute :]


def is_loopback(host: str) -> bool:
    """True for addresses only this machine can reach (127.0.0.0/8, ::1, 'localhost')."""
    import ipaddress

    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:  # a host name other than localhost may resolve to anything
        return False
