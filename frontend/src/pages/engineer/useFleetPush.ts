import { useEffect, useRef } from "react";
import { useAuth } from "../../auth/AuthContext";
import { AlarmSocket, browserSocketUrl } from "../../lib/alarmSocket";

/** Calls `onChange` whenever the backend says the fleet changed (a robot said hello, runs
 * another model or went offline; a deployment changed), pushed on /ws/browser, and each time
 * the socket is live again after a (re)connect (news may have been missed meanwhile). */
export function useFleetPush(onChange: () => void): void {
  const { token, logout } = useAuth();
  const latest = useRef(onChange);
  latest.current = onChange;
  useEffect(() => {
    if (!token) return;
    let wasLive = false;
    const socket = new AlarmSocket(browserSocketUrl(), token, {
      onMessage: (message) => {
        if (message.type === "fleet") latest.current();
      },
      onStatus: (status) => {
        if (status === "live" && wasLive) latest.current(); // the page loaded already the first time
        if (status === "live") wasLive = true;
      },
      onUnauthorized: logout,
    });
    socket.start();
    return () => socket.stop();
  }, [token, logout]);
}
