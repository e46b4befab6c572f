import { useCallback, useEffect, useMemo, useState } from "react";
import { Link, useParams } from "react-router-dom";
import { api, errorMessage } from "../api/client";
import type { components } from "../api/schema";
import type { Alarm } from "../api/types";
import { KIND_LABEL, mayAcknowledge } from "../lib/alarmBoard";
import { robotStateText } from "../lib/robotState";
import { delayFilter } from "../lib/replay";
import { clockTime } from "../lib/time";
import { dispositionLine, robotLabel } from "../lib/dispositions";
import { AuditTrail } from "./AuditTrail";
import { verdictText } from "./labels";
import { ProbabilityChart } from "./ProbabilityChart";
import { ResolveDialog } from "./ResolveDialog";
import { SkeletonCanvas } from "./SkeletonCanvas";
import { useAlarmActions } from "./useAlarmActions";

type Replay = components["schemas"]["AlarmReplayOut"];

const FILTER_TEXT = { idle: "idle", counting: "counting", fired: "fired" } as const;
/** The delay filter's state in a nurse's words. */
const ALARM_TEXT = {
  idle: "no alarm",
  counting: "waiting to be sure",
  fired: "alarm raised",
} as const;

/** Alarm replay (skeleton, Emergency probability, delay filter) and its audit trail. */
export function AlarmDetailPage() {
  const alarmId = Number(useParams().alarmId);
  const [replay, setReplay] = useState<Replay | null>(null);
  const [error, setError] = useState<string | null>(null);
  const [index, setIndex] = useState(0);
  const [playing, setPlaying] = useState(false);
  const [resolving, setResolving] = useState(false);
  const [auditVersion, setAuditVersion] = useState(0);
  const onUpdated = useCallback((alarm: Alarm) => {
    setReplay((r) => (r ? { ...r, alarm } : r));
    setAuditVersion((v) => v + 1);
  }, []);
  const actions = useAlarmActions(onUpdated);

  useEffect(() => {
    let live = true;
    void api.GET("/api/alarms/{alarm_id}/replay", {
      params: { path: { alarm_id: alarmId }, query: { before_s: 5, after_s: 5 } },
    }).then(({ data, error }) => {
      if (!live) return;
      if (!data) return setError(errorMessage(error, `Could not load alarm ${alarmId}`));
      setReplay(data);
      const at = data.frames.findIndex((f) => (f.seq ?? -1) >= (data.alarm.first_seq ?? Infinity));
      setIndex(at >= 0 ? at : 0);
    });
    return () => { live = false; };
  }, [alarmId]);

  const frames = replay?.frames ?? [];
  const alarm = replay?.alarm;
  const steps = useMemo(
    () => delayFilter(frames, alarm?.threshold ?? null, alarm?.delay_ms ?? null),
    [frames, alarm],
  );
  const span = useMemo(() => {
    if (!alarm || alarm.first_seq == null) return null;
    const first = alarm.first_seq;
    const last = alarm.last_seq ?? first;
    const inSpan = frames.filter((f) => f.seq !== null && f.seq >= first && f.seq <= last);
    return inSpan.length ? ([inSpan[0].ts, inSpan[inSpan.length - 1].ts] as const) : null;
  }, [frames, alarm]);

  useEffect(() => {
    if (!playing || frames.length === 0) return;
    const timer = window.setInterval(() => {
      setIndex((i) => {
        if (i + 1 >= frames.length) { setPlaying(false); return i; }
        return i + 1;
      });
    }, 1000 / 15);
    return () => window.clearInterval(timer);
  }, [playing, frames.length]);

  if (error) return <main className="page"><p role="alert" className="error">{error}</p></main>;
  if (!replay || !alarm) return <main className="page"><p className="muted">Loading replay…</p></main>;

  const frame = frames[index];
  const step = steps[index];
  const origin = span?.[0] ?? frames[0]?.ts ?? 0;
  return (
    <main className="page replay" data-frames={frames.length}>
      <p><Link to="/nurse/history">← Alarm history</Link> · <Link to="/nurse">Live board</Link></p>
      <h1>
        {KIND_LABEL[alarm.kind]} alarm #{alarm.id}{" "}
        <span className={`pill state-${alarm.state}`}>{alarm.state}</span>
        {replay.generated && <span className="pill generated">generated data (simulation)</span>}
      </h1>
      <dl className="facts">
        <dt>Robot</dt><dd>{robotLabel(alarm)}</dd>
        {dispositionLine(alarm) && <><dt>Phones</dt><dd data-testid="dispositions">{dispositionLine(alarm)}</dd></>}
        <dt>Patient</dt><dd>{alarm.patient ?? "–"}</dd>
        <dt>Location</dt><dd>{alarm.location ?? "–"}</dd>
        <dt>Raised</dt><dd>{clockTime(alarm.raised_at)}</dd>
        {alarm.robot_state && (
          <><dt>Robot did</dt><dd className={`robot-state robot-${alarm.robot_state}`} data-testid="robot-state">
            {robotStateText(alarm.robot_state, alarm.robot_state_since)}</dd></>
        )}
        <dt>Verdict</dt><dd>{verdictText(alarm.verdict, alarm.reason)}</dd>
        <dt>When it rings</dt>
        <dd>
          {alarm.threshold != null && alarm.delay_ms != null
            ? `when the robot is at least ${Math.round(alarm.threshold * 100)}% sure for ${(alarm.delay_ms / 1000).toFixed(1)} s`
            : "–"}
        </dd>
      </dl>
      <details className="technical">
        <summary>Technical details</summary>
        <dl className="facts">
          <dt>Model version</dt><dd>{alarm.model_version ?? "–"}</dd>
          <dt>Threshold</dt><dd>{alarm.threshold != null ? `threshold ${alarm.threshold.toFixed(2)}` : "–"}</dd>
          <dt>Delay</dt><dd>{alarm.delay_ms != null ? `${alarm.delay_ms} ms` : "–"}</dd>
        </dl>
        {frame && step && (
          <p className="frame-numbers">
            frame {frame.seq} · decision {frame.decision ?? "–"} ·
            P(emergency) {step.emergencyScore?.toFixed(2) ?? "–"} · delay filter{" "}
            <strong className={`filter-${step.state}`}>{FILTER_TEXT[step.state]}</strong>
            {step.state !== "idle" ? ` (${step.heldMs} of ${alarm.delay_ms ?? 0} ms)` : ""}
          </p>
        )}
      </details>
      {alarm.state !== "resolved" && (
        <div className="actions replay-actions">
          {mayAcknowledge(alarm) && (
            <button type="button" className="ack" disabled={actions.busyId === alarm.id}
              onClick={() => void actions.acknowledge(alarm)}>
              Acknowledge
            </button>
          )}
          <button type="button" className="resolve" disabled={actions.busyId === alarm.id}
            onClick={() => { actions.setError(null); setResolving(true); }}>
            Resolve…
          </button>
        </div>
      )}
      {actions.error && !resolving && <p role="alert" className="error">{actions.error}</p>}
      <section className="replay-view">
        <div>
          <SkeletonCanvas frames={frames} index={index}
            color={step?.state === "fired" ? "#ef4444" : step?.rawEmergency ? "#f59e0b" : "#38bdf8"} />
          <div className="replay-controls">
            <button type="button" onClick={() => { if (index + 1 >= frames.length) setIndex(0); setPlaying((p) => !p); }}>
              {playing ? "Pause" : "Play"}
            </button>
            <input type="range" min={0} max={Math.max(0, frames.length - 1)} value={index}
              aria-label="Frame" onChange={(e) => { setPlaying(false); setIndex(Number(e.target.value)); }} />
          </div>
          {frame && step && (
            <p className="frame-info">
              {(frame.ts - origin).toFixed(1)} s · the robot is{" "}
              {step.emergencyScore != null ? `${Math.round(step.emergencyScore * 100)}% ` : ""}sure
              of an emergency ·{" "}
              <strong className={`filter-${step.state}`}>{ALARM_TEXT[step.state]}</strong>
            </p>
          )}
        </div>
        <ProbabilityChart frames={frames} steps={steps} threshold={alarm.threshold ?? null}
          span={span} index={index} onSelect={(i) => { setPlaying(false); setIndex(i); }} />
      </section>
      <h2>Audit trail</h2>
      <AuditTrail key={auditVersion} alarmId={alarm.id} />
      {resolving && (
        <ResolveDialog alarm={alarm} error={actions.error} busy={actions.busyId === alarm.id}
          onSubmit={(r) => void actions.resolve(alarm, r).then((done) => done && setResolving(false))}
          onCancel={() => setResolving(false)} />
      )}
    </main>
  );
}
