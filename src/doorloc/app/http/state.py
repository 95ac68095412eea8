"""What one running service holds: its settings, the cell in use, the recipe store, the CPU limiter.

Loading the cell (and the calibration it names) happens once at start-up; until it has succeeded the
service is alive (``/healthz``) but not ready (``/readyz`` 503), and locate requests are refused 503.
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import dataclass, field
from typing import Any

from doorloc.app.access import FailureBudget, KeyStore
from doorloc.app.answer import LocateFn
from doorloc.app.decodepool import DecodePool, nice_at_least, start_pools
from doorloc.app.fairslots import FairSlots, RecentUse
from doorloc.app.http.metrics import ServiceMetrics
from doorloc.app.settings import ServiceSettings, missing_database
from doorloc.cell import Cell, cell_to_dict
from doorloc.recipes.store import RecipeStore, database_url

__all__ = ["ServiceState"]

_log = logging.getLogger("doorloc.http")


@dataclass
class ServiceState:
    """Mutable state of one app instance (never shared between apps)."""

    settings: ServiceSettings
    metrics: ServiceMetrics
    #: the locate step when it runs in this process's threads (given in code, or decode_in_threads' default);
    #: None while the worker processes locate
    locate_fn: LocateFn | None = None
    cell: Cell | None = None
    #: the recipe database (None until loaded; routes take it after ready_state)
    store: RecipeStore | None = None
    #: the API keys, on the store's database
    keys: KeyStore | None = None
    load_error: str | None = None
    limiter: FairSlots = field(init=False)
    #: the CPU slots of the lower-priority workers (`over_share`), for the jobs of a client over its share of
    #: recent worker time (None: no such workers, settings.over_share_nice == 0, or no worker processes)
    over_share_limiter: FairSlots | None = field(init=False)
    #: each client's recent worker time (seconds held a CPU slot), which decides who is over its share
    recent_use: RecentUse = field(init=False)
    #: locate requests in this worker right now, running or waiting for a CPU slot (routes_locate._cpu_slot)
    admitted: int = 0
    #: True once a key exists or was presented: the service then never answers without one (fails closed)
    keys_seen: bool = False
    auth_failures: FailureBudget = field(init=False)
    #: refused requests (a key, or an upload that is no measurable image) waiting before their answer right now
    #: (admission.hold_refusal)
    refusals_waiting: int = 0
    #: the limited worker processes (None: decode and locate in threads, settings.decode_in_threads). They
    #: decode each image and then locate in it (one job per request; see `decoders` for the exceptions) unless
    #: a locate_fn was given in code (a test's stand-in), which then runs in the thread that asks, on their image
    workers: DecodePool | None = field(init=False)
    #: decoding-only processes (started on first use; None unless the workers locate) for uploads whose
    #: decoding work their header does not bound (admission.decodes_apart): a decoding bomb among them ends one
    #: of these, which restarts in milliseconds, not a worker holding locate's kernels
    decoders: DecodePool | None = field(init=False)
    #: locating workers like `workers`, of lower CPU priority (settings.over_share_nice), for the jobs of a
    #: client over its share of recent worker time: another client's job in `workers` overtakes them on a busy CPU
    over_share: DecodePool | None = field(init=False)
    #: whether this process has lowered its own CPU priority (settings.serve_nice; once, after the workers start)
    serve_niced: bool = False
    #: per client (key name, else address): locate requests running or queued (fair shedding)
    client_admitted: dict[str, int] = field(init=False, default_factory=dict)
    #: per (key, client address) within a key's share: locate requests running or queued
    address_admitted: dict[tuple[str, str], int] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.limiter = FairSlots(self.settings.locate_concurrency)
        self.auth_failures = FailureBudget(self.settings.auth_failures_per_minute)
        self.recent_use = RecentUse()
        self.workers = None
        self.decoders = None
        self.over_share = None
        self.over_share_limiter = None
        if not self.settings.decode_in_threads:
            # the real pipeline is imported by the workers only (each holds locate's kernels; this process
            # never locates, so it does not load numba); a locate given in code runs here
            pipeline = "doorloc.vision.locate:locate" if self.locate_fn is None else None
            self.workers = self._locating_pool(pipeline)
            if pipeline is not None:
                self.decoders = DecodePool(
                    self.settings.locate_concurrency,
                    self.settings.decode_cpu_s,
                    self.settings.decode_memory_bytes,
                )
            if pipeline is not None and self.settings.over_share_nice > 0:
                self.over_share = self._locating_pool(pipeline, nice=self.settings.over_share_nice)
                self.over_share_limiter = FairSlots(self.settings.locate_concurrency)

    def _locating_pool(self, pipeline: str | None, nice: int = 0) -> DecodePool:
        """The worker processes that decode and locate (``pipeline``; None: decode only), one per CPU slot,
        with the settings' limits, at ``nice`` levels below the service."""
        return DecodePool(
            self.settings.locate_concurrency,
            self.settings.decode_cpu_s,
            self.settings.decode_memory_bytes,
            locate_fn=pipeline,
            locate_cpu_s=self.settings.locate_cpu_s,
            locate_memory_bytes=self.settings.locate_memory_bytes,
            nice=nice,
        )

    @property
    def locates_in_workers(self) -> bool:
        """Whether a request's image is decoded and located in one limited worker process (one job)."""
        return self.workers is not None and self.workers.locate_fn is not None

    @property
    def per_client_limit(self) -> int:
        """Locate requests one client may have running or queued in this worker at once."""
        if self.settings.max_per_client is not None:
            return self.settings.max_per_client
        return max(1, self.capacity // 2)

    @property
    def per_address_limit(self) -> int:
        """Locate requests one address may have running or queued under one key in this worker at once."""
        if self.settings.max_per_address is not None:
            return self.settings.max_per_address
        return max(1, -(-self.per_client_limit // 2))

    @property
    def access_mode(self) -> str:
        """'open' while the service answers without a key (open_access, no key seen), else 'keys'."""
        if self.settings.open_access and not self.keys_seen and self.settings.api_key is None:
            return "open"
        return "keys"

    @property
    def capacity(self) -> int:
        """Locate requests one worker admits at once: its CPU slots plus its queue."""
        return self.settings.locate_concurrency + self.settings.max_queue

    @property
    def overloaded(self) -> bool:
        return self.admitted >= self.capacity

    @property
    def recipes(self) -> RecipeStore:
        """The recipe store of a ready service (routes reach it after ``ready_state``)."""
        if self.store is None:
            raise RuntimeError("the recipe store is not loaded (the service is not ready)")
        return self.store

    @property
    def ready(self) -> bool:
        return self.cell is not None and self.store is not None

    def load(self) -> None:
        """Load what is not given yet: the cell from ``settings.cell``, the recipe store from its URL.

        Never raises: a failure is kept in ``load_error`` (shown by /readyz) and logged.
        """
        try:
            if self.cell is None:
                if not self.settings.cell:
                    raise ValueError(
                        "no cell file configured: start with --cell cell.yaml or set DOORLOC_CELL"
                    )
                from doorloc.cell import load_cell

                self.cell = load_cell(self.settings.cell)
            if self.store is None:
                url = database_url(self.settings)
                missing = None if self.settings.create_database else missing_database(url)
                if missing is not None:
                    raise ValueError(missing)
                self.store = RecipeStore(url)
            if self.keys is None and getattr(self.store, "engine", None) is not None:
                self.keys = KeyStore(self.store.engine, derivation_nice=self.settings.key_derivation_nice)
            if self.keys is not None and self.keys.any_active(remember=False):
                self.keys_seen = True
            if self.workers is not None and self.locates_in_workers:
                # the worker processes load locate's compiled kernels now, not in the first request (those
                # still missing: a second call starts none); this process never locates itself
                start_pools([p for p in (self.workers, self.over_share) if p is not None])
                if not self.serve_niced and self.settings.serve_nice > 0:
                    # the workers (forked from a server started before this) keep their priority; this
                    # process goes serve_nice below them, once: a second service in the same process (an
                    # application embedding it, tests) finds it there already
                    base = self.workers.worker_nice()
                    if base is not None:
                        self.serve_niced = nice_at_least(base + self.settings.serve_nice)
            elif self.locate_fn is None:
                from doorloc.app.services import default_locate_fn

                # (it loads locate's compiled kernels now, not in the first request)
                self.locate_fn = default_locate_fn()
            self.load_error = None
            _log.info(
                "ready", extra={"fields": {"event": "ready", "cell": self.settings.cell, **self.cell_ids()}}
            )
        except Exception as e:  # noqa: BLE001 - any start-up failure must leave a readable reason, not a dead process
            self.load_error = str(e) or type(e).__name__
            _log.error("not ready", extra={"fields": {"event": "not_ready", "reason": self.load_error}})

    def cell_ids(self) -> dict[str, str]:
        """Ids of the cell in use and of its camera calibration (for audit trails): ``sha256:`` + the same
        digests every result carries as ``provenance.cell_sha256`` and ``provenance.calibration_sha256``
        (the files' bytes). A cell built in code, with no file, gets the digest of its content instead."""
        if self.cell is None:
            return {}
        doc = cell_to_dict(self.cell)
        camera = {k: doc["camera"][k] for k in ("image_size", "camera_matrix", "dist_coeffs")}
        return {
            "cell_id": "sha256:" + (self.cell.sha256 or _digest(doc)),
            "calibration_id": "sha256:" + (self.cell.calibration_sha256 or _digest(camera)),
        }


def _digest(obj: Any) -> str:
    return hashlib.sha256(
        json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str).encode()
    ).hexdigest()
