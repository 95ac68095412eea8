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

import anyio

from doorloc.app.access import KeyStore
from doorloc.app.answer import LocateFn
from doorloc.app.http.metrics import ServiceMetrics
from doorloc.app.settings import ServiceSettings
from doorloc.cell import Cell, cell_to_dict
from doorloc.recipes.store import RecipeStore, database_url

__all__ = ["ServiceState"]

_log = logging.getLogger("doorloc.http")


@dataclass
class ServiceState:
    """Mutable state of one app instance (never shared between apps)."""

    settings: ServiceSettings
    metrics: ServiceMetrics
    locate_fn: LocateFn | None = None
    cell: Cell | None = None
    #: the recipe database (None until loaded; routes take it after ready_state)
    store: RecipeStore | None = None
    #: the API keys, on the store's database
    keys: KeyStore | None = None
    load_error: str | None = None
    limiter: anyio.CapacityLimiter = field(init=False)
    #: locate requests in this worker right now, running or waiting for a CPU slot (routes_locate._cpu_slot)
    admitted: int = 0

    def __post_init__(self) -> None:
        self.limiter = anyio.CapacityLimiter(self.settings.locate_concurrency)

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
                self.store = RecipeStore(database_url(self.settings))
            if self.keys is None and getattr(self.store, "engine", None) is not None:
                self.keys = KeyStore(self.store.engine)
            if self.locate_fn is None:
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
