"""Prometheus metrics, one registry per app so several apps can live in one process (tests)."""

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram


class Metrics:
    def __init__(self) -> None:
        self.registry = CollectorRegistry()
        self.frames_ingested = Counter(
            "vigil_frames_ingested", "Frames committed to the database", registry=self.registry
        )
        self.ack_latency = Histogram(
            "vigil_ingest_commit_seconds",
            "Time from receiving a frame batch to sending its acknowledgement",
            buckets=(0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0),
            registry=self.registry,
        )
        self.flush_seconds = Histogram(
            "vigil_ingest_flush_seconds",
            "Duration of one batched ingest transaction (all robots' messages of one flush)",
            buckets=(0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5),
            registry=self.registry,
        )
        self.flush_frames = Histogram(
            "vigil_ingest_flush_frames",
            "Frames committed by one batched ingest transaction",
            buckets=(1, 5, 10, 25, 50, 100, 250, 500, 1000, 2500),
            registry=self.registry,
        )
        self.open_alarms = Gauge(
            "vigil_open_alarms", "Alarms not yet resolved", ["kind"], registry=self.registry
        )
        self.connected_robots = Gauge(
            "vigil_connected_robots", "Robots connected to this process", registry=self.registry
        )
