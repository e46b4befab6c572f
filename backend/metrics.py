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
        # Frame storage (the admin's storage page; cached, see backend.storage.service).
        gauge = lambda name, text, labels=(): Gauge(name, text, labels, registry=self.registry)  # noqa: E731
        self.storage_frames = gauge(
            "vigil_storage_frames",
            "Stored frames by robot (robot='' for imported recordings)",
            ["robot"],
        )
        self.storage_bytes = gauge(
            "vigil_storage_bytes",
            "Stored frame bytes by robot (blobs plus a per-row estimate)",
            ["robot"],
        )
        self.storage_day_frames = gauge(
            "vigil_storage_day_frames", "Stored robot frames by UTC day", ["day"]
        )
        self.storage_day_bytes = gauge(
            "vigil_storage_day_bytes", "Stored robot frame bytes by UTC day", ["day"]
        )
        self.storage_database_bytes = gauge(
            "vigil_storage_database_bytes", "Size of the database on disk"
        )
        self.retention_older_frames = gauge(
            "vigil_retention_next_older_frames",
            "Robot frames older than the next retention run's cutoff (at most this many go)",
        )
        self.retention_preview_drop = gauge(
            "vigil_retention_preview_drop_frames",
            "Frames the latest dry run said the policy would drop",
        )
        self.retention_last_dropped = gauge(
            "vigil_retention_last_dropped_frames", "Frames the latest retention run dropped"
        )
        self.storage_archives = gauge("vigil_storage_archives", "Parquet archives of videos")

    def set_storage(self, summary) -> None:
        """Fill the storage gauges from a backend.storage.schemas.StorageSummary."""
        for gauge in (
            self.storage_frames,
            self.storage_bytes,
            self.storage_day_frames,
            self.storage_day_bytes,
        ):
            gauge.clear()
        for robot in summary.robots:
            self.storage_frames.labels(robot.robot_id or "").set(robot.frames)
            self.storage_bytes.labels(robot.robot_id or "").set(robot.bytes)
        for day in summary.days:
            self.storage_day_frames.labels(day.day).set(day.frames)
            self.storage_day_bytes.labels(day.day).set(day.bytes)
        self.storage_database_bytes.set(summary.database_bytes)
        self.retention_older_frames.set(summary.next_run.older_frames)
        preview = summary.next_run.preview
        self.retention_preview_drop.set(preview.dropped_frames if preview else 0)
        real = next((r for r in summary.runs if not r.dry_run and r.status == "done"), None)
        self.retention_last_dropped.set(real.dropped_frames if real else 0)
        self.storage_archives.set(summary.archives)


def summary_ms(values: list[float], count_key: str = "n") -> dict:
    """Count, p50, p99 and max (ms, nearest rank) of measured durations."""
    if not values:
        return {count_key: 0}
    ordered = sorted(values)
    pick = lambda q: round(ordered[min(len(ordered) - 1, int(q * len(ordered)))], 1)  # noqa: E731
    return {
        count_key: len(ordered),
        "p50_ms": pick(0.5),
        "p99_ms": pick(0.99),
        "max_ms": round(ordered[-1], 1),
    }
