"""Service configuration, read once at the edge from ``DOORLOC_*`` environment variables.

Everything the HTTP service needs is one :class:`ServiceSettings` value handed to
:func:`doorloc.app.http.create_app`; nothing reads the environment after that.

Examples
--------
>>> s = ServiceSettings(cell="fixtures/cell_thesis.yaml", max_upload_bytes=1_000_000)
>>> s.max_upload_bytes
1000000
"""

from __future__ import annotations

import os
from typing import Annotated

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from doorloc.app.imagesniff import DEFAULT_MAX_JPEG_SCANS

__all__ = ["ServiceSettings", "default_locate_concurrency", "missing_database"]

#: 20 MB: a lossless 1080p grey PNG is ~1-3 MB, a 4K colour PNG ~15 MB.
DEFAULT_MAX_UPLOAD_BYTES = 20 * 1000 * 1000
#: 50 megapixels: ample for any industrial camera, far below what would exhaust memory when decoded.
DEFAULT_MAX_PIXELS = 50_000_000
#: 100 MB decoded (width x height x channels x bytes per sample): a 4K 16-bit colour frame is 50 MB;
#: a 7000x7000 16-bit RGBA PNG (381 kB on the wire) would be 392 MB
DEFAULT_MAX_DECODED_BYTES = 100_000_000


def default_locate_concurrency(workers: int, cpus: int | None = None) -> int:
    """Images each of ``workers`` service processes locates at once by default: the CPUs shared among them.

    ``cpus`` defaults to the CPUs this process may run on (its affinity: a container's or ``taskset``'s CPU
    set), not every CPU of the machine.

    (Each worker taking every CPU put ``workers`` images on each core: at 16 clients on 2 CPUs with 2
    workers the server spent more CPU per request than one thread does, in the contention.)
    """
    if cpus is None:
        cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, cpus // max(1, workers))


class ServiceSettings(BaseSettings):
    """Configuration of ``doorloc serve`` (environment variables ``DOORLOC_<NAME>``)."""

    model_config = SettingsConfigDict(env_prefix="DOORLOC_", extra="ignore", frozen=True)

    cell: str | None = Field(
        None, description="path of the cell file (cell.yaml) the service locates doors in"
    )
    database_url: str | None = Field(
        None, description="SQLAlchemy URL of the door-recipe database; unset: the recipe store's default"
    )
    api_key: SecretStr | None = Field(
        None, description="when set, every /v1 request must send it as X-API-Key"
    )
    max_upload_bytes: int = Field(DEFAULT_MAX_UPLOAD_BYTES, gt=0, description="largest request body, bytes")
    max_pixels: int = Field(DEFAULT_MAX_PIXELS, gt=0, description="largest image (width*height) decoded")
    max_decoded_bytes: int = Field(
        DEFAULT_MAX_DECODED_BYTES,
        gt=0,
        description="largest decoded image, width*height*channels*bytes per sample",
    )
    max_queue: int = Field(
        8,
        ge=0,
        description="locate requests that may wait for a CPU slot in one worker; more answer 503 Retry-After",
    )
    request_deadline_s: float = Field(
        30.0,
        gt=0,
        description="a locate request that has not got a CPU slot (or its whole body) by then answers 503",
    )
    locate_concurrency: int = Field(
        default_factory=lambda: default_locate_concurrency(1),
        gt=0,
        description="images located at the same time in one worker process (the rest wait their turn); "
        "default: the CPU count shared among `doorloc serve --workers`",
    )
    opencv_threads: int = Field(
        1,
        ge=0,
        description="cv2.setNumThreads for the process: requests run in parallel already, so 1 avoids oversubscription",
    )
    log_level: str = Field("INFO", description="level of the structured request log")

    # ---- access
    open_access: bool = Field(
        False,
        description="serve without API keys (every caller an engineer): only on a loopback address "
        "(doorloc serve --open), and only while no key exists; otherwise every request needs a key",
    )
    create_database: bool = Field(
        False,
        description="create the recipe database when its SQLite file does not exist (else that is an error: "
        "a mistyped URL must not become a fresh, keyless database)",
    )
    allowed_hosts: Annotated[list[str], NoDecode] = Field(
        default_factory=lambda: ["localhost", "127.0.0.1", "::1"],
        description="names the Host header may carry (port ignored); '*' allows any (not with open_access); "
        "doorloc serve adds its --host",
    )
    trusted_proxies: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="addresses of reverse proxies whose X-Forwarded-For / X-Forwarded-Proto are believed; "
        "empty: none (the connection's own address is the client)",
    )
    auth_failures_per_minute: int = Field(
        10,
        ge=1,
        description="wrong or unknown API keys one client address may send per minute; more answer 429",
    )
    auth_refusal_delay_s: float = Field(
        0.5,
        ge=0,
        le=10,
        description="seconds a request refused for its key (401, 429) waits before its answer, so that a flood "
        "of keyless or wrong-key requests is answered a few times a second per connection instead of hundreds; "
        "at most a quarter of max_connections wait at once, the rest are answered at once (0: no wait)",
    )
    image_refusal_delay_s: float = Field(
        0.5,
        ge=0,
        le=10,
        description="seconds an upload refused as no measurable image (415, or 422: empty, malformed, past "
        "the decoding bounds or a worker's CPU-time or memory limit) waits before its answer, so that "
        "a stream of decoding bombs is answered a few times a second per connection; the same cap as "
        "auth_refusal_delay_s on the connections waiting (0: no wait)",
    )

    # ---- the HTTP server itself (uvicorn and its protocol, per connection)
    max_header_bytes: int = Field(
        32 * 1024, ge=1024, description="largest request line plus headers, bytes; more answer 431"
    )
    max_headers: int = Field(100, ge=8, description="most header fields in one request; more answer 431")
    header_timeout_s: float = Field(
        10.0,
        gt=0,
        description="a request line and headers not received by then (from the connection or "
        "the previous answer) answer 408 and the connection is closed",
    )
    body_timeout_s: float = Field(
        30.0, gt=0, description="a request body (other than an image upload) not received by then answers 408"
    )
    keep_alive_s: float = Field(5.0, gt=0, description="an idle keep-alive connection is closed after this")
    max_connections: int = Field(
        256,
        ge=1,
        description="open connections one worker serves; more answer 503 (uvicorn limit_concurrency)",
    )

    # ---- decoding
    max_jpeg_scans: int = Field(
        DEFAULT_MAX_JPEG_SCANS, ge=1, description="scans a JPEG may hold (each is a pass over the image)"
    )
    decode_cpu_s: float = Field(
        10.0,
        gt=0,
        description="CPU seconds one image may take to decode (its worker process is ended then)",
    )
    decode_memory_bytes: int = Field(
        400_000_000,
        gt=0,
        description="memory (address space) a worker process may add while decoding one image, bytes",
    )
    decode_in_threads: bool = Field(
        False,
        description="decode and locate in the service's own threads instead of limited worker processes (no "
        "CPU-time or memory bound beyond the header checks; for tests and debugging)",
    )
    # ---- locating (in the same limited worker process, after decoding: one job per image)
    locate_cpu_s: float = Field(
        10.0,
        gt=0,
        description="CPU seconds locating the door in one image may take (its process is ended then; a 1080p "
        "frame takes about 0.03 s)",
    )
    locate_memory_bytes: int = Field(
        400_000_000,
        gt=0,
        description="memory (address space) locating the door in one image may add to its worker process, the "
        "decoded image held, bytes (a 1080p frame needs under 8 MB)",
    )
    key_derivation_nice: int = Field(
        10,
        ge=0,
        le=19,
        description="nice levels the threads that derive API keys (scrypt, ~50 ms each; a flood of wrong keys "
        "costs one each) run below the serving process, so that its other answers keep the CPU meanwhile; "
        "0: same priority (Linux, where each thread has its own; ignored elsewhere)",
    )
    serve_nice: int = Field(
        5,
        ge=0,
        le=19,
        description="nice levels the serving process (its HTTP event loop, which answers and refuses requests) "
        "lowers its CPU priority by once its worker processes have started, so that a locate in progress "
        "keeps the CPU while many cheap requests are refused; 0: same priority (Unix; ignored elsewhere)",
    )
    over_share_nice: int = Field(
        15,
        ge=0,
        le=19,
        description="nice levels of the extra worker processes (one per CPU slot) that run the jobs of a client "
        "which used more than its share of worker time recently while another client was present, so another "
        "client's job overtakes them on the CPU; 0: no extra workers, every job waits for the CPU slots in "
        "turn (Unix; elsewhere the extra workers run at the same priority)",
    )
    overlay_max_pixels: int = Field(
        8_300_000, gt=0, description="largest image (width*height) an overlay is drawn for (4K UHD)"
    )
    max_per_client: int | None = Field(
        None,
        ge=1,
        description="locate requests one client (API key) may have running or queued in a worker; "
        "default: half the worker's slots plus queue, at least 1",
    )
    max_per_address: int | None = Field(
        None,
        ge=1,
        description="locate requests one client address (after trusted proxies) may have running or queued "
        "under one API key in a worker, so that one machine sharing a key cannot take the key's whole share; "
        "default: half the key's share, rounded up",
    )

    @field_validator("allowed_hosts", "trusted_proxies", mode="before")
    @classmethod
    def _comma_list(cls, v: object) -> object:
        # DOORLOC_ALLOWED_HOSTS=a,b as well as JSON
        if isinstance(v, str) and not v.lstrip().startswith("["):
            return [x.strip() for x in v.split(",") if x.strip()]
        return v

    @field_validator("api_key", "cell", "database_url", mode="before")
    @classmethod
    def _empty_is_unset(cls, v: object) -> object:
        # DOORLOC_API_KEY= (set but empty) must not mean "the key is the empty string"
        return None if v == "" else v


def missing_database(url: str) -> str | None:
    """Why ``url`` names no existing database (a sentence), or None (it exists, or is not a file-backed SQLite URL).

    A mistyped SQLite path would otherwise be created empty, with no recipes and no API keys.
    """
    from sqlalchemy.engine import make_url

    u = make_url(url)
    if not u.get_backend_name() == "sqlite" or u.database in (None, "", ":memory:") or "mode=memory" in url:
        return None
    path = u.database
    if path.startswith("file:"):
        return None  # a URI filename: its options decide
    if os.path.exists(path):
        return None
    return (
        f"the recipe database {path} does not exist; check the URL (DOORLOC_DATABASE_URL / --database-url), or "
        "create it on purpose with doorloc keys create (which also makes the first key) or --create-database"
    )
