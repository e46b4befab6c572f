import { useEffect, useRef } from "react";
import { useAuth } from "../../auth/AuthContext";
import { AlarmSocket, browserSocketUrl } from "../../lib/alarmSocket";
import { coalesce } from "../../lib/coalesce";

/** Fleet news comes with every commit that changes a robot: reload at most this often. */
export const FLEET_RELOAD_MIN_MS = 500;

/** Calls `onChange` whenever the backend says the fleet changed (a robot said hello, runs
 * another model or went offline; a deployment changed), pushed on /ws/browser, and each time
 * the socket is live again after a (re)connect (news may have been missed meanwhile); at most
 * once per FLEET_RELOAD_MIN_MS, ending on the latest news. */
export function useFleetPush(onChange: () => void): void {
  const { token, logout } = useAuth();
  const latest = useRef(onChange);
  latest.current = onChange;
  useEffect(() => {
    if (!token) return;
    let wasLive = false;
    const reload = coalesce(() => latest.current(), FLEET_RELOAD_MIN_MS);
    const socket = new AlarmSocket(browserSocketUrl(), token, {
      onMessage: (message) => {
        if (message.type === "fleet") reload.trigger();
      },
      onStatus: (status) => {
        if (status === "live" && wasLive) reload.trigger(); // the page loaded already the first time
        if (status === "live") wasLive = true;
      },
      onUnauthorized: logout,
    });
    socket.start();
    return () => {
      socket.stop();
      reload.stop();
    };
  }, [token, logout]);
}
