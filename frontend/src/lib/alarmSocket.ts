// The browser's websocket to /ws/browser: reconnects by itself and reports its status.
import type { BrowserMessage } from "../api/types";
import { reconnectDelayMs } from "./backoff";

export type LinkStatus = "connecting" | "live" | "disconnected";

/** Close codes after which reconnecting cannot help (the token is no longer accepted). */
const FATAL_CLOSE_CODES = new Set([4401, 4403, 1008]);
/** A ping every PING_MS; a link silent for STALE_MS is treated as dead (e.g. a tablet's Wi-Fi
 * dropped without the socket noticing) and replaced. */
export const PING_MS = 10_000;
export const STALE_MS = 25_000;

export interface AlarmSocketHandlers {
  onMessage(message: BrowserMessage): void;
  onStatus(status: LinkStatus): void;
  onUnauthorized(): void;
}

/** The subset of WebSocket used here, so tests can pass a fake. */
export interface SocketLike {
  onopen: ((event: unknown) => void) | null;
  onmessage: ((event: { data: unknown }) => void) | null;
  onclose: ((event: { code: number }) => void) | null;
  send(data: string): void;
  close(code?: number, reason?: string): void;
}

/** The socket's URL. It carries no token (access logs record URLs): the token goes in the
 * first message, see authMessage. */
export function browserSocketUrl(location: Location = window.location): string {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  return `${scheme}://${location.host}/ws/browser`;
}

/** The first message on the socket: this tab's session token (each tab may hold its own). */
export function authMessage(token: string): string {
  return JSON.stringify({ type: "auth", token });
}

function isBrowserMessage(value: unknown): value is BrowserMessage {
  if (!value || typeof value !== "object") return false;
  const message = value as { type?: unknown; alarms?: unknown; alarm?: unknown; robots?: unknown };
  return (
    (message.type === "snapshot" && Array.isArray(message.alarms)) ||
    (message.type === "alarm" && typeof message.alarm === "object" && message.alarm !== null) ||
    (message.type === "fleet" && Array.isArray(message.robots))
  );
}

export class AlarmSocket {
  private socket: SocketLike | null = null;
  private attempt = 0;
  private retryTimer: ReturnType<typeof setTimeout> | undefined;
  private pingTimer: ReturnType<typeof setInterval> | undefined;
  private lastHeard = 0;
  private stopped = false;

  constructor(
    private readonly url: string,
    private readonly token: string,
    private readonly handlers: AlarmSocketHandlers,
    private readonly createSocket: (url: string) => SocketLike = (u) => new WebSocket(u) as unknown as SocketLike,
    private readonly now: () => number = Date.now,
  ) {}

  start(): void {
    this.stopped = false;
    this.connect();
  }

  stop(): void {
    this.stopped = true;
    clearTimeout(this.retryTimer);
    clearInterval(this.pingTimer);
    this.socket?.close(1000, "page closed");
    this.socket = null;
  }

  private connect(): void {
    this.handlers.onStatus(this.attempt === 0 ? "connecting" : "disconnected");
    const socket = this.createSocket(this.url);
    this.socket = socket;
    this.lastHeard = this.now();
    socket.onopen = () => {
      this.attempt = 0;
      this.lastHeard = this.now();
      socket.send(authMessage(this.token));
    };
    socket.onmessage = (event) => {
      this.lastHeard = this.now();
      let message: unknown;
      try {
        message = JSON.parse(String(event.data));
      } catch {
        return;
      }
      if (!isBrowserMessage(message)) return; // e.g. {"type": "pong"}
      // The board is live only once the snapshot has arrived: before it, alarms could be missing.
      if (message.type === "snapshot") this.handlers.onStatus("live");
      this.handlers.onMessage(message);
    };
    socket.onclose = (event) => this.closed(socket, event.code);
    clearInterval(this.pingTimer);
    this.pingTimer = setInterval(() => this.keepAlive(socket), PING_MS);
  }

  private keepAlive(socket: SocketLike): void {
    if (this.socket !== socket) return;
    if (this.now() - this.lastHeard > STALE_MS) {
      socket.close(4000, "no answer from server");
      this.closed(socket, 4000);
      return;
    }
    try {
      socket.send("ping");
    } catch {
      // not open yet or already closing: onclose handles it
    }
  }

  private closed(socket: SocketLike, code: number): void {
    if (this.socket !== socket || this.stopped) return;
    this.socket = null;
    clearInterval(this.pingTimer);
    socket.onopen = socket.onmessage = socket.onclose = null;
    this.handlers.onStatus("disconnected");
    if (FATAL_CLOSE_CODES.has(code)) {
      this.handlers.onUnauthorized();
      return;
    }
    const delay = reconnectDelayMs(this.attempt++);
    this.retryTimer = setTimeout(() => this.connect(), delay);
  }
}
