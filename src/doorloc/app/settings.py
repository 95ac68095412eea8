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

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

__all__ = ["ServiceSettings", "default_locate_concurrency"]

#: 20 MB: a lossless 1080p grey PNG is ~1-3 MB, a 4K colour PNG ~15 MB.
DEFAULT_MAX_UPLOAD_BYTES = 20 * 1000 * 1000
#: 50 megapixels: ample for any industrial camera, far below what would exhaust memory when decoded.
DEFAULT_MAX_PIXELS = 50_000_000
#: 100 MB decoded (width x height x channels x bytes per sample): a 4K 16-bit colour frame is 50 MB;
#: a 7000x7000 16-bit RGBA PNG (381 kB on the wire) would be 392 MB
DEFAULT_MAX_DECODED_BYTES = 100_000_000


def default_locate_concurrency(workers: int, cpus: int | None = None) -> int:
    """Images each of ``workers`` service processes locates at once by default: the CPUs shared among them.

    (Each worker taking every CPU put ``workers`` images on each core: at 16 clients on 2 CPUs with 2
    workers the server spent more CPU per request than one thread does, in the contention.)
    """
    return max(1, (cpus if cpus is not None else os.cpu_count() or 1) // max(1, workers))


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

    @field_validator("api_key", "cell", "database_url", mode="before")
    @classmethod
    def _empty_is_unset(cls, v: object) -> object:
        # DOORLOC_API_KEY= (set but empty) must not mean "the key is the empty string"
        return None if v == "" else v
