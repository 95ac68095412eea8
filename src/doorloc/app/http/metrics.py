"""Prometheus metrics of one app instance, in its own registry (no process-global state).

Each ``create_app`` call gets a fresh :class:`ServiceMetrics`, so two apps in one process (tests) never
share counters. ``doorloc serve`` runs prometheus_client's multiprocess mode (``PROMETHEUS_MULTIPROC_DIR``,
set by serve before the workers start): every worker writes its values to files there and ``/metrics``,
whichever worker answers it, adds up all workers' counters and histograms, so a scrape reads the service,
not one worker. Process figures (resident memory, CPU seconds, open files) are reported per worker
(label ``pid``). Internal errors (bugs) are counted apart from refusals.
"""

from __future__ import annotations

import os
import resource

from prometheus_client import (
    CONTENT_TYPE_LATEST,
    CollectorRegistry,
    Counter,
    Gauge,
    Histogram,
    generate_latest,
)

MULTIPROCESS_ENV = "PROMETHEUS_MULTIPROC_DIR"

__all__ = ["ServiceMetrics", "CONTENT_TYPE_LATEST"]

# Locate takes ~0.1-1 s; uploads of a 1080p PNG ~10 ms on a LAN.
_LATENCY_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.5, 5.0, 10.0, 30.0)


class ServiceMetrics:
    """Request counts, latency histogram, locate outcomes and refusals by reason."""

    def __init__(self) -> None:
        from prometheus_client import values

        # multiprocess values only when prometheus_client saw the folder at import (it decides then)
        multi = values.ValueClass is not values.MutexValue
        self.multiprocess_dir = os.environ.get(MULTIPROCESS_ENV) if multi else None
        self.registry = CollectorRegistry(auto_describe=True)
        self.requests = Counter(
            "doorloc_http_requests",
            "HTTP requests answered",
            ["method", "route", "status"],
            registry=self.registry,
        )
        self.latency = Histogram(
            "doorloc_http_request_duration_seconds",
            "Time to answer an HTTP request, seconds",
            ["method", "route"],
            buckets=_LATENCY_BUCKETS,
            registry=self.registry,
        )
        self.locates = Counter(
            "doorloc_locate_results",
            "Images located, by outcome (answered, refused or internal_error)",
            ["outcome"],
            registry=self.registry,
        )
        self.internal_errors = Counter(
            "doorloc_internal_errors",
            "Internal errors (bugs), by where they happened (locate, request)",
            ["where"],
            registry=self.registry,
        )
        self.refusals = Counter(
            "doorloc_locate_refusals",
            "Locate refusals (ok=false) by reason",
            ["reason"],
            registry=self.registry,
        )
        self.locate_seconds = Histogram(
            "doorloc_locate_duration_seconds",
            "Time spent in locate itself (decode excluded), seconds",
            buckets=_LATENCY_BUCKETS,
            registry=self.registry,
        )
        self.rejected_uploads = Counter(
            "doorloc_rejected_uploads",
            "Uploads refused before locate, by reason",
            ["reason"],
            registry=self.registry,
        )
        self.in_flight = Gauge(
            "doorloc_locate_in_flight",
            "Locate requests in progress (waiting for a CPU slot or running)",
            registry=self.registry,
            multiprocess_mode="livesum",
        )
        self.worker_rss = Gauge(
            "doorloc_worker_resident_memory_bytes",
            "Resident memory of each worker process, bytes",
            registry=self.registry,
            multiprocess_mode="liveall",
        )
        self.worker_cpu = Gauge(
            "doorloc_worker_cpu_seconds",
            "CPU time used by each worker process (user + system), seconds",
            registry=self.registry,
            multiprocess_mode="liveall",
        )
        self.worker_fds = Gauge(
            "doorloc_worker_open_fds",
            "Open file descriptors of each worker process",
            registry=self.registry,
            multiprocess_mode="liveall",
        )

    def observe_request(self, method: str, route: str, status: int, seconds: float) -> None:
        self.requests.labels(method, route, str(status)).inc()
        self.latency.labels(method, route).observe(seconds)

    def observe_locate(self, ok: bool, reason: str | None, elapsed_ms: float) -> None:
        self.locate_seconds.observe(elapsed_ms / 1e3)
        if ok:
            self.locates.labels("answered").inc()
        elif reason == "internal_error":  # a bug, not a judgement about the image
            self.locates.labels("internal_error").inc()
            self.internal_errors.labels("locate").inc()
        else:
            self.locates.labels("refused").inc()
            self.refusals.labels(reason or "unknown").inc()

    def sample_process(self) -> None:
        """Refresh this worker's process figures (called periodically and before each scrape)."""
        usage = resource.getrusage(resource.RUSAGE_SELF)
        self.worker_cpu.set(usage.ru_utime + usage.ru_stime)
        try:
            with open("/proc/self/statm") as f:
                self.worker_rss.set(int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE"))
            self.worker_fds.set(len(os.listdir("/proc/self/fd")))
        except OSError:  # not Linux: peak RSS (kB on Linux, bytes on macOS) is the best there is
            self.worker_rss.set(usage.ru_maxrss * 1024)

    def exposition(self) -> bytes:
        """The Prometheus text format: this app's registry, or in multiprocess mode all workers together."""
        self.sample_process()
        if self.multiprocess_dir is None:
            return generate_latest(self.registry)
        from prometheus_client import multiprocess

        combined = CollectorRegistry()
        multiprocess.MultiProcessCollector(combined, path=self.multiprocess_dir)
        return generate_latest(combined)
