import { useCallback, useEffect, useState } from "react";
import type { Alarm } from "../api/types";
import { useAuth } from "../auth/AuthContext";
import { applyMessage, emptyBoard, type Board } from "../lib/alarmBoard";
import { AlarmSocket, browserSocketUrl, type LinkStatus } from "../lib/alarmSocket";

/** The live board from /ws/browser, plus a way to apply REST responses without waiting for the push. */
export function useAlarmBoard(): { board: Board; status: LinkStatus; update(alarm: Alarm): void } {
  const { token, logout } = useAuth();
  const [board, setBoard] = useState<Board>(emptyBoard);
  const [status, setStatus] = useState<LinkStatus>("connecting");

  useEffect(() => {
    if (!token) return;
    const socket = new AlarmSocket(browserSocketUrl(), token, {
      onMessage: (message) => setBoard((b) => applyMessage(b, message)),
      onStatus: setStatus,
      onUnauthorized: logout,
    });
    socket.start();
    return () => socket.stop();
  }, [token, logout]);

  const update = useCallback(
    (alarm: Alarm) => setBoard((b) => applyMessage(b, { type: "alarm", alarm })),
    [],
  );
  return { board, status, update };
}
