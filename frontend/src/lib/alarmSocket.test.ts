import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import type { BrowserMessage } from "../api/types";
import {
  AlarmSocket,
  browserSocketUrl,
  PING_MS,
  STALE_MS,
  type LinkStatus,
  type SocketLike,
} from "./alarmSocket";

class FakeSocket implements SocketLike {
  onopen: SocketLike["onopen"] = null;
  onmessage: SocketLike["onmessage"] = null;
  onclose: SocketLike["onclose"] = null;
  sent: string[] = [];
  closed = false;
  send(data: string) {
    this.sent.push(data);
  }
  close() {
    this.closed = true;
  }
  serverSays(message: object) {
    this.onmessage?.({ data: JSON.stringify(message) });
  }
}

describe("AlarmSocket", () => {
  let sockets: FakeSocket[];
  let statuses: LinkStatus[];
  let messages: BrowserMessage[];
  let unauthorized: number;
  let socket: AlarmSocket;

  beforeEach(() => {
    vi.useFakeTimers();
    sockets = [];
    statuses = [];
    messages = [];
    unauthorized = 0;
    socket = new AlarmSocket(
      "ws://x/ws/browser",
      "tab-token",
      {
        onMessage: (m) => messages.push(m),
        onStatus: (s) => statuses.push(s),
        onUnauthorized: () => unauthorized++,
      },
      () => {
        const s = new FakeSocket();
        sockets.push(s);
        return s;
      },
      () => Date.now(),
    );
  });
  afterEach(() => {
    socket.stop();
    vi.useRealTimers();
  });

  it("sends the token in its first message, never in the URL", () => {
    socket.start();
    sockets[0].onopen?.({});
    expect(sockets[0].sent).toEqual([JSON.stringify({ type: "auth", token: "tab-token" })]);
    expect(browserSocketUrl({ protocol: "https:", host: "h:1" } as Location)).toBe("wss://h:1/ws/browser");
  });

  it("is live only after the snapshot and ignores other messages", () => {
    socket.start();
    sockets[0].onopen?.({});
    expect(statuses).toEqual(["connecting"]);
    sockets[0].serverSays({ type: "pong" });
    sockets[0].serverSays({ type: "snapshot", alarms: [] });
    expect(statuses).toEqual(["connecting", "live"]);
    expect(messages).toEqual([{ type: "snapshot", alarms: [] }]);
  });

  it("hands on the fleet's news, and drops a fleet message without its robots", () => {
    socket.start();
    sockets[0].onopen?.({});
    sockets[0].serverSays({ type: "snapshot", alarms: [] });
    sockets[0].serverSays({ type: "fleet" });
    sockets[0].serverSays({ type: "fleet", robots: ["robot-a"] });
    expect(messages).toEqual([
      { type: "snapshot", alarms: [] },
      { type: "fleet", robots: ["robot-a"] },
    ]);
  });

  it("reconnects after a drop and reports disconnected meanwhile", () => {
    socket.start();
    sockets[0].serverSays({ type: "snapshot", alarms: [] });
    sockets[0].onclose?.({ code: 1006 });
    expect(statuses.at(-1)).toBe("disconnected");
    vi.advanceTimersByTime(700);
    expect(sockets).toHaveLength(2);
    sockets[1].serverSays({ type: "snapshot", alarms: [] });
    expect(statuses.at(-1)).toBe("live");
  });

  it("pings and replaces a link that went silent", () => {
    socket.start();
    sockets[0].serverSays({ type: "snapshot", alarms: [] });
    vi.advanceTimersByTime(PING_MS);
    expect(sockets[0].sent).toEqual(["ping"]);
    vi.advanceTimersByTime(STALE_MS);
    expect(sockets[0].closed).toBe(true);
    expect(statuses.at(-1)).toBe("disconnected");
    vi.advanceTimersByTime(1000);
    expect(sockets).toHaveLength(2);
  });

  it("stops retrying when the token is refused", () => {
    socket.start();
    sockets[0].onclose?.({ code: 4401 });
    vi.advanceTimersByTime(60_000);
    expect(sockets).toHaveLength(1);
    expect(unauthorized).toBe(1);
  });
});
