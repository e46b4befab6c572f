// The browser's websocket to /ws/browser: reconnects by itself and reports its status.
import type { BrowserMessage } from "../api/types";
import { reconnectDelayMs } from "./backoff";

export type LinkStatus = "connecting" | "live" | "disconnected";

/** Close codes after which reconnecting cannot help (the token is no longer accepted). */
const FATAL_CLOSE_CODES = new Set([4401, 4403, 1008]);

export interface AlarmSocketHandlers {
  onMessage(message: BrowserMessage): void;
  onStatus(status: LinkStatus): void;
  onUnauthorized(): void;
}

export function browserSocketUrl(token: string, location: Location = window.location): string {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  return `${scheme}://${location.host}/ws/browser?token=${encodeURIComponent(token)}`;
}

export class AlarmSocket {
  private socket: WebSocket | null = null;
  private attempt = 0;
  private retryTimer: number | undefined;
  private stopped = false;

  constructor(
    private readonly url: string,
    private readonly handlers: AlarmSocketHandlers,
  ) {}

  start(): void {
    this.stopped = false;
    this.connect();
  }

  stop(): void {
    this.stopped = true;
    window.clearTimeout(this.retryTimer);
    this.socket?.close(1000, "page closed");
    this.socket = null;
  }

  private connect(): void {
    this.handlers.onStatus(this.attempt === 0 ? "connecting" : "disconnected");
    const socket = new WebSocket(this.url);
    this.socket = socket;
    socket.onopen = () => {
      this.attempt = 0;
    };
    socket.onmessage = (event) => {
      let message: BrowserMessage;
      try {
        message = JSON.parse(String(event.data)) as BrowserMessage;
      } catch {
        return;
      }
      // The board is live only once the snapshot has arrived: before it, alarms could be missing.
      if (message.type === "snapshot") this.handlers.onStatus("live");
      this.handlers.onMessage(message);
    };
    socket.onclose = (event) => {
      if (this.socket !== socket || this.stopped) return;
      this.socket = null;
      if (FATAL_CLOSE_CODES.has(event.code)) {
        this.handlers.onStatus("disconnected");
        this.handlers.onUnauthorized();
        return;
      }
      this.handlers.onStatus("disconnected");
      const delay = reconnectDelayMs(this.attempt++);
      this.retryTimer = window.setTimeout(() => this.connect(), delay);
    };
  }
}
