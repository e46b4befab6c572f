"""The nurse board under a shift's load, in a real browser: 500 unresolved alarms in the ward,
then 10 new Emergencies a minute for 30 minutes, with one 10 s network drop between the browser
and the server.

Real backend (uvicorn subprocess, SQLite), real websockets, Debian Chromium via Playwright. The
browser reaches the backend through a TCP relay in this process, which the benchmark cuts for
10 s (every connection closed, new ones refused): a network drop as the tablet sees it. The new
alarms come from a simulated robot (GENERATED skeletons) over the robot protocol; the 500
alarms already there are GENERATED rows written to the database before the board opens (60 %
missed Emergencies, 20 % acknowledged Emergencies, 10 % open Pause, 10 % open technical), so
that no Emergency calls when the shift starts and the tone can be timed for each new one.

Per new Emergency: robot's frame sent -> the alarm is the first row of the board, and -> the tone
plays (both stamped in the page by a MutationObserver, on the same clock as the sender). The
bench then acknowledges it as a nurse would (REST), so the tone stops before the next one; the
re-alarm of acknowledged alarms is set beyond the run (VIGIL_REALARM_MINUTES) for the same
reason. Alarms raised while the link is down are reported apart (they wait for the reconnect).
Also: first render of the board (navigation start -> 500 rows), JS heap (after a forced GC) at
the start and the end, console errors, and after the reconnect the board's alarm ids against
the database's unresolved ones (duplicates, missing, extra).

    python -m bench.nurse_soak [--minutes 30] [--rate 10] [--seed-alarms 500]
    VIGIL_SOAK_MINUTES=2 python -m bench.nurse_soak --out /tmp/nurse_soak.json  # a quick check
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import re
import socket
import statistics
import tempfile
import threading
import time
from collections import Counter
from datetime import timedelta
from pathlib import Path

import httpx
from playwright.sync_api import sync_playwright
from sqlalchemy import select

from backend.db import make_engine, make_session_factory, transaction
from backend.models import Alarm, Robot, Transport, User
from backend.models._types import utcnow
from backend.models.alarms import PRIORITY_OF_KIND, AlarmKind, AlarmState
from tests.browser.live_server import (
    CHROMIUM,
    CHROMIUM_ARGS,
    ROBOT_ID,
    ROBOT_TOKEN,
    TABLET,
    LiveServer,
    build_frontend,
    list_alarm_ids,
    sign_in,
)
from tests.browser.simulated_robot import SimulatedRobot, fall_frames
from vigil.protocol import TransportEnd

WARD = "ward-a"
GOALS = {
    "first_render_ms": 1000,
    "top_p95_ms": 250,
    "tone_p95_ms": 250,
    "heap_growth_mb": 50,
    "console_errors": 0,
    "duplicates": 0,
    "missing": 0,
}
#: Chromium reports a refused request or a dropped socket on the console; during the drop these
#: are the network's doing, not the page's (tests/browser/conftest.py uses the same rule).
NETWORK_CONSOLE = re.compile(r"Failed to load resource|WebSocket connection to .* failed|net::ERR_")

# Stamps in the page, on the epoch clock: when each alarm id first became the board's first
# row, when a beep of the tone was made (and when the board said "sounding"), when the link went
# live or down, and (since navigation start) when the board first held `expected` rows.
OBSERVER = """
(() => {
  const soak = (window.__soak = { top: {}, tone: [], firstRender: null, live: [], playing: false,
    beeps: [] });
  const expected = %d;
  const stamp = () => performance.timeOrigin + performance.now();
  // The tone itself: every beep creates its oscillators (frontend/src/lib/alarmSound.ts).
  const create = AudioContext.prototype.createOscillator;
  AudioContext.prototype.createOscillator = function (...args) {
    soak.beeps.push(stamp());
    return create.apply(this, args);
  };
  const check = () => {
    const board = document.querySelector("main.board");
    if (!board) return;
    const first = board.querySelector("[data-alarm-id]");
    const id = first && first.getAttribute("data-alarm-id");
    if (id && !(id in soak.top)) soak.top[id] = stamp();
    const playing = board.getAttribute("data-audio-state") === "playing";
    if (playing && !soak.playing) soak.tone.push(stamp());
    soak.playing = playing;
    const live = board.getAttribute("data-link") === "live";
    if (live !== (soak.live.length %% 2 === 1)) soak.live.push(stamp());
    // First render: the list holds every alarm (it draws the rows in view, AlarmList.tsx) and
    // its first row is drawn.
    const list = board.querySelector(".alarm-list[data-alarm-count]");
    if (soak.firstRender === null && id && list
        && Number(list.getAttribute("data-alarm-count")) >= expected)
      soak.firstRender = performance.now();
  };
  new MutationObserver(check).observe(document, { subtree: true, childList: true, attributes: true,
    attributeFilter: ["data-alarm-id", "data-audio-state", "data-link", "data-alarm-count"] });
})();
"""


class Relay:
    """A TCP relay browser -> backend that can drop the network: close every connection and
    refuse new ones until restored."""

    def __init__(self, upstream_port: int) -> None:
        self.upstream_port = upstream_port
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.down = threading.Event()
        self.connections: set[socket.socket] = set()
        self.lock = threading.Lock()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            if self.down.is_set():
                client.close()
                continue
            try:
                upstream = socket.create_connection(("127.0.0.1", self.upstream_port))
            except OSError:
                client.close()
                continue
            with self.lock:
                self.connections |= {client, upstream}
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pipe, args=(a, b), daemon=True).start()

    def _pipe(self, source: socket.socket, sink: socket.socket) -> None:
        try:
            while data := source.recv(65536):
                sink.sendall(data)
        except OSError:
            pass
        finally:
            for s in (source, sink):
                with self.lock:
                    self.connections.discard(s)
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)
                s.close()

    def drop(self) -> None:
        self.down.set()
        with self.lock:
            doomed = list(self.connections)
        for s in doomed:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)

    def restore(self) -> None:
        self.down.clear()

    def close(self) -> None:
        self.drop()
        self.listener.close()


def seed_alarms(database_url: str, count: int) -> None:
    """`count` GENERATED unresolved alarms in the ward, one per ended transport, the newest a
    minute ago, spread over robot-a and four more robots of the ward."""
    engine = make_engine(database_url)
    now = utcnow()
    with transaction(make_session_factory(engine)) as session:
        robots = [ROBOT_ID] + [f"robot-{c}" for c in "bcde"]
        for robot_id in robots[1:]:
            session.add(Robot(id=robot_id, name=robot_id, ward=WARD))
        nurse = session.scalars(select(User).where(User.username == "nina")).one()
        session.flush()
        for i in range(count):
            robot_id = robots[i % len(robots)]
            raised = now - timedelta(seconds=60 + 50 * (count - i))
            transport = Transport(
                id=f"seed-{i}",
                robot_id=robot_id,
                mode="walking",
                patient=f"GEN-{i:03d}",
                location=f"generated room {i % 40}",
                started_at=raised - timedelta(seconds=20),
                ended_at=raised + timedelta(seconds=20),
                last_frame_at=raised + timedelta(seconds=20),
            )
            session.add(transport)
            session.flush()  # the alarm's foreign key needs the row
            slot = i % 10
            kind = (
                AlarmKind.EMERGENCY
                if slot < 8
                else AlarmKind.PAUSE
                if slot == 8
                else AlarmKind.STREAM_STALLED
            )
            state = (
                AlarmState.MISSED
                if slot < 6
                else AlarmState.ACKNOWLEDGED
                if slot < 8
                else AlarmState.OPEN
            )
            acknowledged = state == AlarmState.ACKNOWLEDGED
            session.add(
                Alarm(
                    kind=kind,
                    priority=PRIORITY_OF_KIND[kind],
                    state=state,
                    robot_id=robot_id,
                    transport_id=transport.id,
                    transport_key=transport.id,
                    ward=WARD,
                    patient=transport.patient,
                    location=transport.location,
                    raised_at=raised,
                    updated_at=raised + timedelta(minutes=4),
                    acknowledged_at=raised + timedelta(seconds=40) if acknowledged else None,
                    acknowledged_by_id=nurse.id if acknowledged else None,
                    escalation_level=3 if state == AlarmState.MISSED else 0,
                    escalated_at=raised + timedelta(minutes=3)
                    if state == AlarmState.MISSED
                    else None,
                    decision_count=1,
                    model_version="generated-soak",
                )
            )
    engine.dispose()


def unresolved_ids(database_url: str) -> set[int]:
    engine = make_engine(database_url)
    try:
        with make_session_factory(engine)() as session:
            return set(
                session.scalars(
                    select(Alarm.id).where(Alarm.ward == WARD, Alarm.state != AlarmState.RESOLVED)
                )
            )
    finally:
        engine.dispose()


def alarm_of_transport(database_url: str, transport_id: str, timeout_s: float = 30) -> int:
    engine = make_engine(database_url)
    deadline = time.monotonic() + timeout_s
    try:
        while True:
            with make_session_factory(engine)() as session:
                found = session.scalar(
                    select(Alarm.id).where(
                        Alarm.transport_id == transport_id, Alarm.kind == AlarmKind.EMERGENCY
                    )
                )
            if found is not None or time.monotonic() > deadline:
                return found
            time.sleep(0.05)
    finally:
        engine.dispose()


def summary(values_ms: list[float]) -> dict:
    if not values_ms:
        return {"n": 0}
    ordered = sorted(values_ms)
    pick = lambda q: ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]  # noqa: E731
    return {
        "n": len(ordered),
        "p50_ms": round(statistics.median(ordered), 1),
        "p95_ms": round(pick(0.95), 1),
        "max_ms": round(ordered[-1], 1),
    }


def heap_mb(cdp) -> float:
    cdp.send("HeapProfiler.collectGarbage")
    metrics = {m["name"]: m["value"] for m in cdp.send("Performance.getMetrics")["metrics"]}
    return round(metrics["JSHeapUsedSize"] / 2**20, 2)


def board_ids(page) -> list[int]:
    return list_alarm_ids(page)


def reconcile(page, database_url: str) -> dict:
    shown = board_ids(page)
    expected = unresolved_ids(database_url)
    counts = Counter(shown)
    return {
        "cards": len(shown),
        "unresolved_in_database": len(expected),
        "duplicates": sum(n - 1 for n in counts.values() if n > 1),
        "missing": len(expected - set(counts)),
        "extra": len(set(counts) - expected),
    }


def run(minutes: float, rate_per_min: float, seed_count: int, drop_s: float) -> dict:
    total = max(1, round(minutes * rate_per_min))
    period_s = 60.0 / rate_per_min
    drop_at = total // 2  # the drop starts right after this alarm's slot
    top, tone, during_drop = [], [], []
    errors: list[str] = []
    network_errors = 0
    result: dict = {}
    with tempfile.TemporaryDirectory() as workdir, sync_playwright() as playwright:
        server = LiveServer.create(Path(workdir), build_frontend(), realarm_minutes="1000000")
        seed_alarms(server.database_url, seed_count)
        server.start()
        relay = Relay(server.port)
        base = f"http://127.0.0.1:{relay.port}"
        browser = playwright.chromium.launch(
            executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS
        )
        try:
            token = server.login()
            headers = {"Authorization": f"Bearer {token}"}
            context = browser.new_context(viewport=TABLET)
            context.add_init_script(OBSERVER % seed_count)
            page = context.new_page()

            def on_console(message) -> None:
                nonlocal network_errors
                if message.type != "error":
                    return
                if NETWORK_CONSOLE.search(message.text):
                    network_errors += 1
                else:
                    errors.append(f"console: {message.text}")

            page.on("console", on_console)
            page.on("pageerror", lambda error: errors.append(f"page error: {error}"))
            sign_in(page, base)
            page.locator("main.board[data-link='live']").wait_for(timeout=30_000)
            # First render: a fresh load of the board with the session already there.
            page.reload()
            page.wait_for_function(
                "() => window.__soak && window.__soak.firstRender !== null", timeout=60_000
            )
            first_render_ms = page.evaluate("() => window.__soak.firstRender")
            live_ms = page.evaluate(
                "() => window.__soak.live.length ? window.__soak.live[0] - performance.timeOrigin"
                " : null"
            )
            loaded_ms = page.evaluate(
                "() => performance.getEntriesByType('navigation')[0].domContentLoadedEventEnd"
            )
            page.get_by_role("button", name="Start shift").click()
            page.locator("main.board[data-audio-state='ready']").wait_for()
            cdp = context.new_cdp_session(page)
            cdp.send("Performance.enable")
            heap_start = heap_mb(cdp)
            after_reconnect = None
            started = time.monotonic()
            with SimulatedRobot(server.robot_ws_url, ROBOT_ID, ROBOT_TOKEN) as robot:
                seq = 0
                drop_window: tuple[float, float] | None = None
                for i in range(total):
                    slot = started + i * period_s
                    time.sleep(max(0.0, slot - time.monotonic()))
                    transport = f"soak-{i}"
                    frames = fall_frames(seq, time.time() - 5, transport)
                    seq += len(frames)
                    first = next(k for k, f in enumerate(frames) if f.decision == "emergency")
                    robot.start_transport(
                        transport, patient=f"GEN-S{i:03d}", location="generated corridor"
                    )
                    robot.send_batch(frames[:first])
                    robot.send_batch(frames[first : first + 1])
                    sent = time.time() * 1000
                    robot.wait_ack(frames[first].seq)
                    alarm_id = alarm_of_transport(server.database_url, transport)
                    in_drop = drop_window is not None and drop_window[1] == 0.0
                    timeout_ms = 60_000 if in_drop else 15_000
                    page.wait_for_function(
                        "([id, sent]) => window.__soak.top[id] !== undefined"
                        " && window.__soak.beeps.some((t) => t >= sent)",
                        arg=[str(alarm_id), sent],
                        timeout=timeout_ms,
                    )
                    stamps = page.evaluate(
                        "([id, sent]) => [window.__soak.top[id],"
                        " window.__soak.beeps.find((t) => t >= sent)]",
                        [str(alarm_id), sent],
                    )
                    row = {
                        "alarm": alarm_id,
                        "top_ms": stamps[0] - sent,
                        "tone_ms": stamps[1] - sent,
                    }
                    if in_drop:
                        during_drop.append(row)
                    else:
                        top.append(row["top_ms"])
                        tone.append(row["tone_ms"])
                    httpx.post(
                        f"{server.base_url}/api/alarms/{alarm_id}/acknowledge",
                        headers=headers,
                        timeout=10,
                    ).raise_for_status()
                    page.locator("main.board[data-audio-state='ready']").wait_for(
                        timeout=timeout_ms
                    )
                    if i == drop_at:
                        relay.drop()
                        drop_window = (time.monotonic(), 0.0)
                        page.locator("main.board[data-link='disconnected']").wait_for(
                            timeout=15_000
                        )
                        threading.Timer(drop_s, relay.restore).start()
                    elif (
                        drop_window is not None
                        and drop_window[1] == 0.0
                        and page.locator("main.board[data-link='live']").count()
                    ):
                        drop_window = (drop_window[0], time.monotonic())
                        time.sleep(1.0)  # let the snapshot settle
                        after_reconnect = reconcile(page, server.database_url)
                        # link down -> live again, from the page's own stamps
                        live = page.evaluate("() => window.__soak.live")
                        after_reconnect["link_down_s"] = (
                            round((live[-1] - live[-2]) / 1000, 1) if len(live) >= 3 else None
                        )
                    robot.send_batch(frames[first + 1 :])
                    robot.send(TransportEnd(transport_id=transport, ts=time.time()))
                    robot.wait_ack(frames[-1].seq)
            if after_reconnect is None:  # the run ended before the link was back
                page.locator("main.board[data-link='live']").wait_for(timeout=60_000)
                time.sleep(1.0)
                after_reconnect = reconcile(page, server.database_url)
            time.sleep(1.0)
            at_end = reconcile(page, server.database_url)
            heap_end = heap_mb(cdp)
            duration_s = time.monotonic() - started
        finally:
            browser.close()
            relay.close()
            server.stop()
    top_s, tone_s = summary(top), summary(tone)
    result = {
        "benchmark": "nurse_soak",
        "what": "the nurse board in Chromium: first render with the seeded alarms; per new "
        "Emergency, robot frame sent -> first row of the board (top) and -> first beep of the "
        "tone created in the page's AudioContext (tone); JS heap after a forced GC at start "
        "and end; console errors; board vs database after a network drop",
        "data": "GENERATED: seeded alarm rows and the simulated robot's stick-figure falls "
        "(tests/browser/simulated_robot.py); this measures the board, not detection",
        "settings": {
            "seeded_alarms": seed_count,
            "rate_per_min": rate_per_min,
            "minutes": minutes,
            "new_alarms": total,
            "drop_s": drop_s,
            "drop_after_alarm": drop_at,
            "view": "list (automatic above 24 alarms)",
        },
        "first_render_ms": round(first_render_ms, 1),
        "first_render_note": "navigation start -> the board holds every seeded alarm (sign-in "
        "kept, page loaded, socket connected, snapshot received, rendered); board_live_ms: "
        "navigation start -> snapshot received; dom_content_loaded_ms: the page's own load",
        "board_live_ms": round(live_ms, 1) if live_ms is not None else None,
        "dom_content_loaded_ms": round(loaded_ms, 1),
        "top": top_s,
        "tone": tone_s,
        "during_drop": [
            {k: round(v, 1) if isinstance(v, float) else v for k, v in r.items()}
            for r in during_drop
        ],
        "heap_mb": {
            "start": heap_start,
            "end": heap_end,
            "growth": round(heap_end - heap_start, 2),
        },
        "console_errors": len(errors),
        "console_error_texts": errors[:20],
        "network_console_messages_during_drop": network_errors,
        "after_reconnect": after_reconnect,
        "at_end": at_end,
        "duration_s": round(duration_s, 1),
        "goals": GOALS,
        "machine": {
            "cpus": os.cpu_count(),
            "load_avg_1m": round(os.getloadavg()[0], 2),
            "python": platform.python_version(),
            "database": "sqlite",
        },
        "measured_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    result["goals_met"] = {
        "first_render": result["first_render_ms"] <= GOALS["first_render_ms"],
        "top_p95": top_s.get("p95_ms", 1e9) <= GOALS["top_p95_ms"],
        "tone_p95": tone_s.get("p95_ms", 1e9) <= GOALS["tone_p95_ms"],
        "heap_growth": result["heap_mb"]["growth"] <= GOALS["heap_growth_mb"],
        "console_errors": not errors,
        "after_reconnect": bool(after_reconnect)
        and after_reconnect["duplicates"] == 0
        and after_reconnect["missing"] == 0,
    }
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--minutes", type=float, default=float(os.environ.get("VIGIL_SOAK_MINUTES", "30"))
    )
    parser.add_argument("--rate", type=float, default=10.0, help="new alarms per minute")
    parser.add_argument("--seed-alarms", type=int, default=500)
    parser.add_argument("--drop-s", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=Path("bench/results/nurse_soak.json"))
    args = parser.parse_args()
    result = run(args.minutes, args.rate, args.seed_alarms, args.drop_s)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
