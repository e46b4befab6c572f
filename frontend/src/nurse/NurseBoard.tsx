import { useCallback, useEffect, useMemo, useState } from "react";
import type { Alarm } from "../api/types";
import { useAuth } from "../auth/AuthContext";
import {
  bannerEmergency,
  countBoard,
  filterBoard,
  inWard,
  GROUP_LABEL,
  needsAttention,
  robotsOf,
  soundRequired,
  sortForBoard,
  TRIAGE_GROUPS,
  triageGroup,
  wardsOf,
  type TriageGroup,
} from "../lib/alarmBoard";
import { pauseAudio, pauseHolds, pauseLeft, type AudioPause } from "../lib/audioPause";
import { useNow } from "../lib/useNow";
import { AlarmCard } from "./AlarmCard";
import { AlarmList } from "./AlarmList";
import { EmergencyBanner } from "./EmergencyBanner";
import { ResolveDialog, type Resolution } from "./ResolveDialog";
import { useAlarmActions } from "./useAlarmActions";
import { useAlarmBoard } from "./useAlarmBoard";
import { useAlarmNotifications } from "./useAlarmNotifications";
import { useAlarmSound } from "./useAlarmSound";
import { askNotificationPermission } from "../lib/notify";

type View = "cards" | "list";
/** Above this many alarms the board shows the compact list unless the nurse picked cards. */
export const LIST_VIEW_ABOVE = 24;

export function NurseBoard() {
  const { user } = useAuth();
  const { board, status, update } = useAlarmBoard();
  const [ward, setWard] = useState<string | null>(user?.ward ?? null);
  const [robot, setRobot] = useState<string | null>(null);
  const [group, setGroup] = useState<TriageGroup | null>(null);
  const [chosenView, setChosenView] = useState<View | null>(null);
  const [resolving, setResolving] = useState<Alarm | null>(null);
  const { busyId, error, setError, acknowledge, resolve: resolveAlarm } = useAlarmActions(update);
  const now = useNow(1000);

  // The ward's alarms (the server sends only wards the nurse may see), then the filters.
  const inWards = useMemo(() => inWard(board.values(), ward), [board, ward]);
  const shown = useMemo(() => sortForBoard(filterBoard(inWards, { ward: null, robot, group })), [inWards, robot, group]);
  const counts = useMemo(() => countBoard(inWards), [inWards]);
  const wards = useMemo(() => {
    const all = wardsOf(board.values());
    if (user?.ward && !all.includes(user.ward)) all.unshift(user.ward);
    return all;
  }, [board, user]);
  const robots = useMemo(() => robotsOf(inWards), [inWards]);
  const view: View = chosenView ?? (shown.length > LIST_VIEW_ABOVE ? "list" : "cards");

  // Sound and banner follow the whole ward, whatever the filters hide.
  const [audioPause, setAudioPause] = useState<AudioPause | null>(null);
  const paused = pauseHolds(audioPause, inWards, now);
  useEffect(() => { if (audioPause && !paused) setAudioPause(null); }, [audioPause, paused]);
  const sound = useAlarmSound(soundRequired(inWards) && !paused);
  const banner = useMemo(() => bannerEmergency(inWards), [inWards]);
  useAlarmNotifications(inWards, status);
  const [notifications, setNotifications] = useState(() =>
    typeof Notification === "undefined" ? "unsupported" : Notification.permission);
  const startShift = () => {
    void sound.unlock();
    void askNotificationPermission().then(setNotifications);
  };

  async function resolve(alarm: Alarm, resolution: Resolution) {
    if (await resolveAlarm(alarm, resolution)) setResolving(null);
  }
  const startResolve = useCallback((a: Alarm) => { setError(null); setResolving(a); }, [setError]);
  const onAcknowledge = useCallback((a: Alarm) => void acknowledge(a), [acknowledge]);

  const openCount = useMemo(() => inWards.filter(needsAttention).length, [inWards]);
  const titleCount = openCount + counts.missed;
  useEffect(() => {
    document.title = titleCount ? `(${titleCount}) Alarms · Vigil` : "Alarms · Vigil";
    return () => { document.title = "Vigil"; };
  }, [titleCount]);

  // Memoised on the board: the clock's tick re-renders the page, not the list's layout.
  const groups = useMemo(
    () => TRIAGE_GROUPS.map((g) => ({ group: g, alarms: shown.filter((a) => triageGroup(a) === g) }))
      .filter((g) => g.alarms.length > 0),
    [shown],
  );

  return (
    <main className="board" data-audio-state={sound.state} data-link={status} data-view={view}>
      {status !== "live" && (
        <div className="banner banner-disconnected" role="alert">
          {status === "connecting"
            ? "Connecting to the alarm server…"
            : "Disconnected from the alarm server — reconnecting. Alarms may be missing until this banner disappears."}
        </div>
      )}
      {sound.state === "locked" && (
        <div className="banner banner-locked" role="status">
          <span>Sound is locked: the browser plays no alarm sound until you start your shift.</span>
          <button type="button" className="primary" onClick={startShift}>
            Start shift
          </button>
        </div>
      )}
      {banner && (
        <EmergencyBanner banner={banner} now={now} busy={busyId === banner.alarm.id}
          onAcknowledge={onAcknowledge} />
      )}
      <div className="board-head">
        <h1>Alarms</h1>
        <span className="count" aria-live="polite" data-testid="board-counts">
          {counts.new} need attention · {counts.missed} missed · {counts.acknowledged} acknowledged
          <span className="count-kinds"> ({counts.emergency} Emergency, {counts.technical} technical, {counts.pause} Pause)</span>
        </span>
        {notifications === "default" && sound.state !== "locked" && (
          <button type="button" className="notify-on"
            onClick={() => void askNotificationPermission().then(setNotifications)}>
            Notify me on this device
          </button>
        )}
        {notifications === "denied" && (
          <span className="notify-denied" role="status">Notifications blocked in this browser: alarms show only while the board is open</span>
        )}
        <span className={`audio audio-${sound.state}`}>
          {sound.state === "playing" ? "● sounding" : sound.state === "ready" ? "sound on" : "sound locked"}
        </span>
        {sound.state === "playing" && (
          <button type="button" onClick={() => setAudioPause(pauseAudio(inWards, Date.now()))}>
            Pause audio 2 min
          </button>
        )}
        {audioPause && paused && (
          <span className="audio-paused" role="status" data-testid="audio-paused">
            Audio paused: {pauseLeft(audioPause, now)} left (a new Emergency sounds at once){" "}
            <button type="button" onClick={() => setAudioPause(null)}>Resume audio</button>
          </span>
        )}
      </div>
      <div className="board-filters">
        <label className="ward-select">
          Ward{" "}
          <select value={ward ?? ""} onChange={(e) => setWard(e.target.value || null)}>
            {!user?.ward && <option value="">All wards</option>}
            {wards.filter((w) => !user?.ward || w === user.ward).map((w) => <option key={w} value={w}>{w}</option>)}
          </select>
        </label>
        <label>
          Robot{" "}
          <select value={robot ?? ""} onChange={(e) => setRobot(e.target.value || null)}>
            <option value="">All robots</option>
            {robots.map((r) => <option key={r} value={r}>{r}</option>)}
            {robot && !robots.includes(robot) && <option value={robot}>{robot}</option>}
          </select>
        </label>
        <label>
          State{" "}
          <select value={group ?? ""} onChange={(e) => setGroup((e.target.value || null) as TriageGroup | null)}>
            <option value="">All states</option>
            {TRIAGE_GROUPS.map((g) => <option key={g} value={g}>{GROUP_LABEL[g]} ({counts[g]})</option>)}
          </select>
        </label>
        <span className="view-switch" role="group" aria-label="View">
          <button type="button" aria-pressed={view === "cards"} onClick={() => setChosenView("cards")}>Cards</button>
          <button type="button" aria-pressed={view === "list"} onClick={() => setChosenView("list")}>List</button>
        </span>
      </div>
      {error && !resolving && <p role="alert" className="error">{error}</p>}
      {shown.length === 0 ? (
        <p className="empty">
          {status !== "live" ? "Waiting for the alarm server…" : inWards.length ? "No alarm matches the filters." : "No open alarms."}
        </p>
      ) : view === "list" ? (
        <AlarmList groups={groups} now={now} busyId={busyId}
          onAcknowledge={onAcknowledge} onResolve={startResolve} />
      ) : (
        groups.map(({ group: g, alarms }) => (
          <section key={g} className={`alarm-group group-${g}`} aria-label={GROUP_LABEL[g]} data-group={g}>
            <h2>{GROUP_LABEL[g]} <span className="group-count">{alarms.length}</span></h2>
            <div className="alarm-grid">
              {alarms.map((alarm) => (
                <AlarmCard key={alarm.id} alarm={alarm} now={now} busy={busyId === alarm.id}
                  onAcknowledge={onAcknowledge} onResolve={startResolve} />
              ))}
            </div>
          </section>
        ))
      )}
      {resolving && (
        <ResolveDialog alarm={resolving} error={error} busy={busyId === resolving.id}
          onSubmit={(r) => void resolve(resolving, r)} onCancel={() => setResolving(null)} />
      )}
    </main>
  );
}
