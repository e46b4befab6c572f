import { useEffect, useMemo, useState } from "react";
import type { Alarm } from "../api/types";
import { useAuth } from "../auth/AuthContext";
import { inWard, needsAttention, soundRequired, sortForBoard, wardsOf } from "../lib/alarmBoard";
import { pauseAudio, pauseHolds, pauseLeft, type AudioPause } from "../lib/audioPause";
import { useNow } from "../lib/useNow";
import { AlarmCard } from "./AlarmCard";
import { ResolveDialog, type Resolution } from "./ResolveDialog";
import { useAlarmActions } from "./useAlarmActions";
import { useAlarmBoard } from "./useAlarmBoard";
import { useAlarmSound } from "./useAlarmSound";

export function NurseBoard() {
  const { user } = useAuth();
  const { board, status, update } = useAlarmBoard();
  const [ward, setWard] = useState<string | null>(user?.ward ?? null);
  const [resolving, setResolving] = useState<Alarm | null>(null);
  const { busyId, error, setError, acknowledge, resolve: resolveAlarm } = useAlarmActions(update);
  const now = useNow(1000);

  const shown = useMemo(() => sortForBoard(inWard(board.values(), ward)), [board, ward]);
  const wards = useMemo(() => {
    const all = wardsOf(board.values());
    if (user?.ward && !all.includes(user.ward)) all.unshift(user.ward);
    return all;
  }, [board, user]);
  const [audioPause, setAudioPause] = useState<AudioPause | null>(null);
  const paused = pauseHolds(audioPause, shown, now);
  useEffect(() => { if (audioPause && !paused) setAudioPause(null); }, [audioPause, paused]);
  const sound = useAlarmSound(soundRequired(shown) && !paused);

  async function resolve(alarm: Alarm, resolution: Resolution) {
    if (await resolveAlarm(alarm, resolution)) setResolving(null);
  }

  const openCount = shown.filter(needsAttention).length;
  useEffect(() => {
    document.title = openCount ? `(${openCount}) Alarms · Vigil` : "Alarms · Vigil";
    return () => { document.title = "Vigil"; };
  }, [openCount]);

  return (
    <main className="board" data-audio-state={sound.state} data-link={status}>
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
          <button type="button" className="primary" onClick={() => void sound.unlock()}>
            Start shift
          </button>
        </div>
      )}
      <div className="board-head">
        <h1>Alarms</h1>
        <span className="count" aria-live="polite">
          {openCount} need attention · {shown.length} open
        </span>
        <label className="ward-select">
          Ward{" "}
          <select value={ward ?? ""} onChange={(e) => setWard(e.target.value || null)}>
            <option value="">All wards</option>
            {wards.map((w) => <option key={w} value={w}>{w}</option>)}
          </select>
        </label>
        <span className={`audio audio-${sound.state}`}>
          {sound.state === "playing" ? "● sounding" : sound.state === "ready" ? "sound on" : "sound locked"}
        </span>
        {sound.state === "playing" && (
          <button type="button" onClick={() => setAudioPause(pauseAudio(shown, Date.now()))}>
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
      {error && !resolving && <p role="alert" className="error">{error}</p>}
      {shown.length === 0 ? (
        <p className="empty">{status === "live" ? "No open alarms." : "Waiting for the alarm server…"}</p>
      ) : (
        <section className="alarm-grid" aria-label="Open alarms">
          {shown.map((alarm) => (
            <AlarmCard key={alarm.id} alarm={alarm} now={now} busy={busyId === alarm.id}
              onAcknowledge={(a) => void acknowledge(a)} onResolve={(a) => { setError(null); setResolving(a); }} />
          ))}
        </section>
      )}
      {resolving && (
        <ResolveDialog alarm={resolving} error={error} busy={busyId === resolving.id}
          onSubmit={(r) => void resolve(resolving, r)} onCancel={() => setResolving(null)} />
      )}
    </main>
  );
}
