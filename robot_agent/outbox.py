"""The robot's outbox: a local SQLite file holding every message until the backend has it.

Every classified frame gets the next sequence number (persistent across restarts, never reused)
and stays until the backend acknowledges a sequence number at least as high. Transport start/end
messages sit in the same ordered queue; one is confirmed once a frame queued after it is
acknowledged (the backend handles a connection's messages in order), and is resent after a
reconnect until then (the backend treats a repeated start/end as a no-op).

Durability: SQLite in WAL mode with synchronous=NORMAL: every commit survives a crash of the
agent. After an Emergency frame a background thread fsyncs the write-ahead log (a few ms later,
off the frame path: an fsync takes milliseconds), so Emergency frames also survive a power cut;
a power cut may lose the last Normal frames written before it.

Disk policy (``budget_bytes`` counts the stored message bodies): when a new frame pushes the
outbox over its budget, the oldest unacknowledged **Normal** frames are dropped first, then the
oldest **Pause** frames. **Emergency** frames (decided Emergency, or on their way to it during
the delay filter) and transport messages are never dropped: if only they remain, the outbox
grows past its budget and says so in the log. Dropped frames are counted (``dropped_total``,
persistent) and reported in the log and in heartbeats.
"""

from __future__ import annotations

import logging
import os
import sqlite3
import threading
import time
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path

from vigil.protocol import frame_json

log = logging.getLogger(__name__)

SCHEMA = """
CREATE TABLE IF NOT EXISTS outbox (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    seq INTEGER UNIQUE,            -- frames only
    after_seq INTEGER NOT NULL,    -- control messages: the last frame seq queued before them
    priority INTEGER NOT NULL,     -- Priority: which rows the disk policy may drop first
    body TEXT NOT NULL,            -- JSON; a frame's: vigil.protocol.frame_body_json
    created REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS outbox_priority ON outbox (priority, id);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);
"""
INSERT_ROW = "INSERT INTO outbox (seq, after_seq, priority, body, created) VALUES (?, ?, ?, ?, ?)"


class Priority(IntEnum):
    """Drop order under the disk budget: lowest first; KEPT rows are never dropped."""

    NORMAL = 0
    PAUSE = 1
    KEPT = 2  # Emergency frames and transport messages


@dataclass(frozen=True, slots=True)
class PendingMessage:
    row_id: int
    seq: int | None  # None for transport messages
    text: str  # a frame as FrameRecord JSON (protocol.frame_json); a transport message whole


@dataclass(frozen=True, slots=True)
class OutboxStatus:
    pending_frames: int
    pending_messages: int
    pending_bytes: int
    next_seq: int
    acked_seq: int | None
    dropped_total: int
    oldest_unacked_emergency: float | None  # wall-clock time it was queued


class WalSyncer:
    """fsyncs the SQLite write-ahead log on request, in its own thread."""

    def __init__(self, wal_path: Path) -> None:
        self.wal_path = wal_path
        self.synced = 0
        self._wanted = threading.Event()
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name="outbox-fsync", daemon=True)
        self._thread.start()

    def request(self) -> None:
        self._wanted.set()

    def _run(self) -> None:
        while True:
            self._wanted.wait()
            self._wanted.clear()
            if self._stopping:
                return
            try:
                fd = os.open(self.wal_path, os.O_RDONLY)
            except FileNotFoundError:  # checkpointed into the database file, which is synced
                continue
            try:
                os.fsync(fd)
                self.synced += 1
            except OSError as error:
                log.error("outbox: fsync of %s failed: %s", self.wal_path, error)
            finally:
                os.close(fd)

    def stop(self) -> None:
        self._stopping = True
        self._wanted.set()
        self._thread.join(5)


class Outbox:
    """Not thread-safe: use it from one thread (the agent's event loop)."""

    def __init__(self, path: Path | str, budget_bytes: int = 200_000_000) -> None:
        if budget_bytes <= 0:
            raise ValueError("budget_bytes must be positive")
        self.path = Path(path)
        self.budget_bytes = budget_bytes
        if str(path) != ":memory:":
            self.path.parent.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(str(path), isolation_level=None, check_same_thread=False)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self._db.executescript(SCHEMA)
        self._next_seq = self._meta("next_seq", 0)
        self._acked_seq = self._meta("acked_seq", -1)
        self._dropped = self._meta("dropped_total", 0)
        self._bytes = self._db.execute(
            "SELECT COALESCE(SUM(LENGTH(body)), 0) FROM outbox"
        ).fetchone()[0]
        self._over_budget_warned = False
        self._syncer = None if str(path) == ":memory:" else WalSyncer(Path(f"{path}-wal"))

    # --- meta ------------------------------------------------------------------------------
    def _meta(self, key: str, default: int) -> int:
        row = self._db.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return default if row is None else int(row[0])

    def _set_meta(self, key: str, value: int) -> None:
        self._db.execute(
            "INSERT INTO meta (key, value) VALUES (?, ?) "
            "ON CONFLICT (key) DO UPDATE SET value = excluded.value",
            (key, value),
        )

    @property
    def next_seq(self) -> int:
        return self._next_seq

    @property
    def dropped_total(self) -> int:
        return self._dropped

    @property
    def pending_bytes(self) -> int:
        return self._bytes

    # --- writing ---------------------------------------------------------------------------
    def add_frame(self, body: str, priority: Priority) -> int:
        """Queue a frame (protocol.frame_body_json: no "seq"); returns its sequence number."""
        seq = self._next_seq
        self._db.execute("BEGIN")
        try:
            self._db.execute(INSERT_ROW, (seq, seq - 1, int(priority), body, time.time()))
            self._set_meta("next_seq", seq + 1)
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        if priority == Priority.KEPT and self._syncer is not None:
            self._syncer.request()  # to the disk itself, off the frame path
        self._next_seq = seq + 1
        self._bytes += len(body)
        if self._bytes > self.budget_bytes:
            self._enforce_budget()
        return seq

    def add_message(self, text: str) -> None:
        """Queue a transport message (a whole protocol message as JSON); never dropped."""
        self._db.execute(
            INSERT_ROW,
            (None, self._next_seq - 1, int(Priority.KEPT), text, time.time()),
        )
        self._bytes += len(text)

    def _enforce_budget(self) -> None:
        excess = self._bytes - self.budget_bytes
        dropped = 0
        self._db.execute("BEGIN")
        try:
            for priority in (Priority.NORMAL, Priority.PAUSE):
                while excess > 0:
                    rows = self._db.execute(
                        "SELECT id, LENGTH(body) FROM outbox WHERE priority = ? "
                        "ORDER BY id LIMIT 256",
                        (int(priority),),
                    ).fetchall()
                    if not rows:
                        break
                    chosen = []
                    for row_id, size in rows:
                        chosen.append((row_id,))
                        excess -= size
                        self._bytes -= size
                        if excess <= 0:
                            break
                    self._db.executemany("DELETE FROM outbox WHERE id = ?", chosen)
                    dropped += len(chosen)
            self._dropped += dropped
            self._set_meta("dropped_total", self._dropped)
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            self._bytes = self._db.execute(
                "SELECT COALESCE(SUM(LENGTH(body)), 0) FROM outbox"
            ).fetchone()[0]
            raise
        if dropped:
            log.warning(
                "outbox over its budget of %d bytes: dropped the %d oldest unsent Normal/Pause "
                "frames (%d dropped in total)",
                self.budget_bytes,
                dropped,
                self._dropped,
            )
        if excess > 0 and not self._over_budget_warned:
            self._over_budget_warned = True
            log.warning(
                "outbox holds %d bytes, over its budget of %d: only Emergency frames and "
                "transport messages are left and those are never dropped",
                self._bytes,
                self.budget_bytes,
            )
        elif excess <= 0:
            self._over_budget_warned = False

    # --- the backend's answers -------------------------------------------------------------
    def acknowledge(self, seq: int) -> int:
        """The backend committed every frame up to `seq`: forget them (and the transport messages
        queued before them). Returns how many rows were removed."""
        if seq <= self._acked_seq:
            return 0
        self._db.execute("BEGIN")
        removed = self._db.execute(
            "SELECT COUNT(*), COALESCE(SUM(LENGTH(body)), 0) FROM outbox "
            "WHERE seq <= ? OR (seq IS NULL AND after_seq < ?)",
            (seq, seq),
        ).fetchone()
        self._db.execute(
            "DELETE FROM outbox WHERE seq <= ? OR (seq IS NULL AND after_seq < ?)", (seq, seq)
        )
        self._acked_seq = seq
        self._set_meta("acked_seq", seq)
        self._db.execute("COMMIT")
        self._bytes -= removed[1]
        return removed[0]

    def on_welcome(self, last_seq: int | None) -> None:
        """Align with what the backend already stored for this robot.

        If the backend holds sequence numbers this outbox never handed out (a fresh outbox file
        on a robot that streamed before, a re-installed robot), the waiting frames are
        renumbered after `last_seq`; the backend would otherwise take them for duplicates and
        drop them. An outbox that was never welcomed cannot have sent anything yet, so on its
        first welcome every number up to `last_seq` belongs to someone else.
        """
        first_welcome = not self._meta("welcomed", 0)
        if last_seq is not None and (
            last_seq >= self._next_seq or (first_welcome and self._lowest_pending_seq() <= last_seq)
        ):
            self._renumber_after(last_seq)
        if first_welcome:
            self._set_meta("welcomed", 1)
        if last_seq is not None:
            self.acknowledge(last_seq)

    def _renumber_after(self, last_seq: int) -> None:
        offset = last_seq + 1 - self._lowest_pending_seq()
        self._db.execute("BEGIN")
        # Two steps: shifting in place could collide with the UNIQUE seq of a later row.
        self._db.execute("UPDATE outbox SET seq = -seq - 1 WHERE seq IS NOT NULL")
        self._db.execute(
            "UPDATE outbox SET seq = -seq - 1 + ?, after_seq = after_seq + ? WHERE seq IS NOT NULL",
            (offset, offset),
        )
        self._db.execute("UPDATE outbox SET after_seq = after_seq + ? WHERE seq IS NULL", (offset,))
        self._next_seq += offset
        self._set_meta("next_seq", self._next_seq)
        self._db.execute("COMMIT")
        log.warning(
            "the backend already holds frames up to seq %d that this outbox did not send "
            "(new outbox file?): the waiting frames are numbered from %d on",
            last_seq,
            self._lowest_pending_seq(),
        )

    def _lowest_pending_seq(self) -> int:
        row = self._db.execute("SELECT MIN(seq) FROM outbox WHERE seq IS NOT NULL").fetchone()
        return self._next_seq if row[0] is None else int(row[0])

    # --- reading ---------------------------------------------------------------------------
    def pending(self, after_row: int = 0, limit: int = 500) -> list[PendingMessage]:
        """Unacknowledged messages queued after row `after_row`, oldest first."""
        rows = self._db.execute(
            "SELECT id, seq, body FROM outbox WHERE id > ? ORDER BY id LIMIT ?", (after_row, limit)
        ).fetchall()
        return [
            PendingMessage(row_id, seq, body if seq is None else frame_json(seq, body))
            for row_id, seq, body in rows
        ]

    def last_row_id(self) -> int:
        return self._db.execute("SELECT COALESCE(MAX(id), 0) FROM outbox").fetchone()[0]

    def oldest_unacked_emergency(self) -> float | None:
        """When the oldest Emergency frame still waiting for its acknowledgement was queued."""
        return self._db.execute(
            "SELECT MIN(created) FROM outbox WHERE priority = ? AND seq IS NOT NULL",
            (int(Priority.KEPT),),
        ).fetchone()[0]

    def status(self) -> OutboxStatus:
        frames, messages = self._db.execute("SELECT COUNT(seq), COUNT(*) FROM outbox").fetchone()
        oldest = self.oldest_unacked_emergency()
        return OutboxStatus(
            pending_frames=frames,
            pending_messages=messages,
            pending_bytes=self._bytes,
            next_seq=self._next_seq,
            acked_seq=None if self._acked_seq < 0 else self._acked_seq,
            dropped_total=self._dropped,
            oldest_unacked_emergency=oldest,
        )

    def close(self) -> None:
        if self._syncer is not None:
            self._syncer.stop()
        self._db.close()
