"""Local SQLite outbox: every frame gets the next sequence number and stays until acknowledged.

Control messages (transport_start, transport_end) travel through the same outbox so the
backend sees them in order with the frames.

Disk policy: at most ``max_frames`` unacknowledged frames are kept. When a new frame would
exceed that, the oldest frames that are NOT Emergency are dropped (and counted in
``dropped``). Emergency frames are never dropped, even past the limit; acknowledged frames are
deleted at once.
"""

from __future__ import annotations

import json
import sqlite3
import threading
from dataclasses import dataclass
from pathlib import Path

_SCHEMA = """
CREATE TABLE IF NOT EXISTS items (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    seq INTEGER UNIQUE,          -- NULL for control messages
    emergency INTEGER NOT NULL DEFAULT 0,
    body TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);
"""


@dataclass(frozen=True, slots=True)
class OutboxItem:
    id: int
    seq: int | None  # None: a control message
    body: dict


class Outbox:
    def __init__(self, path: Path | str, max_frames: int = 200_000) -> None:
        if max_frames < 1:
            raise ValueError("max_frames must be at least 1")
        self.path = Path(path)
        self.max_frames = max_frames
        if str(path) != ":memory:":
            self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self._db.executescript(_SCHEMA)
        self._db.execute(
            "INSERT OR IGNORE INTO meta VALUES ('next_seq', 0), ('dropped', 0), ('synced', 0)"
        )
        self._frames = self._db.execute("SELECT count(*) FROM items WHERE seq IS NOT NULL")
        self._frames = self._frames.fetchone()[0]

    def close(self) -> None:
        with self._lock:
            self._db.close()

    def _meta(self, key: str) -> int:
        return self._db.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()[0]

    @property
    def next_seq(self) -> int:
        with self._lock:
            return self._meta("next_seq")

    @property
    def dropped(self) -> int:
        with self._lock:
            return self._meta("dropped")

    def __len__(self) -> int:
        """Unacknowledged frames."""
        return self._frames

    def put_frame(self, body: dict, emergency: bool) -> int:
        """Store one frame (``body`` without seq); returns its sequence number."""
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                seq = self._meta("next_seq")
                body = {**body, "seq": seq}
                self._db.execute(
                    "INSERT INTO items (seq, emergency, body) VALUES (?, ?, ?)",
                    (seq, int(emergency), json.dumps(body, separators=(",", ":"))),
                )
                self._db.execute("UPDATE meta SET value = ? WHERE key = 'next_seq'", (seq + 1,))
                self._frames += 1
                if self._frames > self.max_frames:
                    self._drop_oldest_normal(self._frames - self.max_frames)
                self._db.execute("COMMIT")
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
            return seq

    def put_control(self, body: dict) -> None:
        with self._lock:
            self._db.execute(
                "INSERT INTO items (seq, body) VALUES (NULL, ?)",
                (json.dumps(body, separators=(",", ":")),),
            )

    def _drop_oldest_normal(self, count: int) -> None:
        cursor = self._db.execute(
            "DELETE FROM items WHERE id IN (SELECT id FROM items WHERE seq IS NOT NULL "
            "AND emergency = 0 ORDER BY id LIMIT ?)",
            (count,),
        )
        self._frames -= cursor.rowcount
        self._db.execute(
            "UPDATE meta SET value = value + ? WHERE key = 'dropped'", (cursor.rowcount,)
        )

    def welcome(self, last_seq: int | None) -> int:
        """The backend's welcome: it holds this robot's frames up to ``last_seq``.

        An outbox that never talked to the backend (first start, or a replaced disk) numbered
        its frames from 0: they are renumbered to follow ``last_seq`` so the backend does not
        take them for frames it already has. Then acts as an ack."""
        with self._lock:
            synced = self._meta("synced")
            if not synced and last_seq is not None:
                self._db.execute("BEGIN IMMEDIATE")
                low = self._db.execute("SELECT min(seq) FROM items").fetchone()[0]
                shift = 0 if low is None else max(0, last_seq + 1 - low)
                if shift:
                    rows = self._db.execute(
                        "SELECT id, seq, body FROM items WHERE seq IS NOT NULL ORDER BY seq DESC"
                    ).fetchall()
                    for item_id, seq, body in rows:
                        data = json.loads(body)
                        data["seq"] = seq + shift
                        self._db.execute(
                            "UPDATE items SET seq = ?, body = ? WHERE id = ?",
                            (seq + shift, json.dumps(data, separators=(",", ":")), item_id),
                        )
                    self._db.execute(
                        "UPDATE meta SET value = value + ? WHERE key = 'next_seq'", (shift,)
                    )
                self._db.execute("UPDATE meta SET value = 1 WHERE key = 'synced'")
                self._db.execute("COMMIT")
            elif not synced:
                self._db.execute("UPDATE meta SET value = 1 WHERE key = 'synced'")
        return self.ack(last_seq)

    def ack(self, seq: int | None) -> int:
        """The backend committed every frame up to ``seq``: delete them (and the control
        messages before them). Returns how many frames were removed."""
        if seq is None:
            return 0
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            # Never hand out a sequence number the backend already holds (e.g. a new outbox file).
            if self._meta("next_seq") <= seq:
                self._db.execute("UPDATE meta SET value = ? WHERE key = 'next_seq'", (seq + 1,))
            row = self._db.execute(
                "SELECT max(id) FROM items WHERE seq IS NOT NULL AND seq <= ?", (seq,)
            ).fetchone()
            frames = 0
            if row[0] is not None:
                frames = self._db.execute(
                    "SELECT count(*) FROM items WHERE seq IS NOT NULL AND id <= ?", (row[0],)
                ).fetchone()[0]
                self._db.execute("DELETE FROM items WHERE id <= ?", (row[0],))
            self._db.execute("COMMIT")
            self._frames -= frames
            return frames

    def pending(self, after_id: int = 0, limit: int = 500) -> list[OutboxItem]:
        """Unacknowledged items with id > after_id, oldest first."""
        with self._lock:
            rows = self._db.execute(
                "SELECT id, seq, body FROM items WHERE id > ? ORDER BY id LIMIT ?",
                (after_id, limit),
            ).fetchall()
        return [OutboxItem(i, s, json.loads(b)) for i, s, b in rows]

    def emergency_count(self) -> int:
        with self._lock:
            return self._db.execute(
                "SELECT count(*) FROM items WHERE emergency = 1 AND seq IS NOT NULL"
            ).fetchone()[0]
