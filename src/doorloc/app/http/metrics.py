"""Prometheus metrics of one app instance, in its own registry (no process-global state).

Each ``create_app`` call gets a fresh :class:`ServiceMetrics`, so two apps in one process (tests) never
share counters. With ``doorloc serve --workers N`` every worker process answers ``/metrics`` for itself.
"""

from __future__ import annotations

from prometheus_client import (
    CONTENT_TYPE_LATEST,
    CollectorRegistry,
    Counter,
    Gauge,
    Histogram,
    generate_latest,
)

__all__ = ["ServiceMetrics", "CONTENT_TYPE_LATEST"]

# Locate takes ~0.1-1 s; uploads of a 1080p PNG ~10 ms on a LAN.
_LATENCY_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.5, 5.0, 10.0, 30.0)


class ServiceMetrics:
    """Request counts, latency histogram, locate outcomes and refusals by reason."""

    def __init__(self) -> None:
        self.registry = CollectorRegistry(auto_describe=True)
        self.requests = Counter(
            "doorloc_http_requests", "HTTP requests answered", ["method", "route", "status"], registry=self.registry
        )
        self.latency = Histogram(
            "doorloc_http_request_duration_seconds", "Time to answer an HTTP request, seconds",
            ["method", "route"], buckets=_LATENCY_BUCKETS, registry=self.registry,
        )
        self.locates = Counter(
            "doorloc_locate_results", "Images located, by outcome (answered or refused)", ["outcome"],
            registry=self.registry,
        )
        self.refusals = Counter(
            "doorloc_locate_refusals", "Locate refusals (ok=false) by reason", ["reason"], registry=self.registry
        )
        self.locate_seconds = Histogram(
            "doorloc_locate_duration_seconds", "Time spent in locate itself (decode excluded), seconds",
            buckets=_LATENCY_BUCKETS, registry=self.registry,
        )
        self.rejected_uploads = Counter(
            "doorloc_rejected_uploads", "Uploads refused before locate, by reason", ["reason"], registry=self.registry
        )
        self.in_flight = Gauge(
            "doorloc_locate_in_flight", "Locate requests in progress (waiting for a CPU slot or running)", registry=self.registry
        )

    def observe_request(self, method: str, route: str, status: int, seconds: float) -> None:
        self.requests.labels(method, route, str(status)).inc()
        self.latency.labels(method, route).observe(seconds)

    def observe_locate(self, ok: bool, reason: str | None, elapsed_ms: float) -> None:
        self.locates.labels("answered" if ok else "refused").inc()
        self.locate_seconds.observe(elapsed_ms / 1e3)
        if not ok:
            self.refusals.labels(reason or "unknown").inc()

    def exposition(self) -> bytes:
        """The Prometheus text format of everything in this registry."""
        return generate_latest(self.registry)
