import { Fragment, useEffect, useState, type FormEvent } from "react";
import { Link, useParams } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import { goldSplitText, metricName, statusText, type GoldSplit } from "../../lib/registry";
import { ConfirmDialog } from "./ConfirmDialog";
import { JobProgress } from "./JobProgress";
import { inputsText } from "./FleetPage";
import { fmt, type Deployment, type FleetRobot, type GateReport, type GoldEvent, type JobKind, type ModelDetail } from "./types";
import { useJob } from "./useJobPolling";

const TABLE3 = ["frame_recall", "frame_precision", "frame_f1", "fp", "fp_d", "fp_d_over_fp", "fn", "fn_d",
  "fn_d_over_fn", "falls_detected", "falls_total", "adl_false_alarms", "adl_total", "median_time_to_alarm_s",
  "max_time_to_alarm_s", "event_f1"];

export function ModelPage() {
  const modelId = Number(useParams().modelId);
  const [model, setModel] = useState<ModelDetail | null>(null);
  const [gate, setGate] = useState<GateReport | null>(null);
  const [error, setError] = useState<string | null>(null);
  const [jobId, setJobId] = useState<number | null>(null);
  const job = useJob(jobId);

  const load = () => {
    void api.GET("/api/models/{model_id}", { params: { path: { model_id: modelId } } }).then(({ data, error }) => {
      if (data) setModel(data); else setError(errorMessage(error, "Could not load the model"));
    });
    void api.GET("/api/models/{model_id}/gate", { params: { path: { model_id: modelId } } }).then(({ data }) => {
      if (data) setGate(data as unknown as GateReport);
    });
  };
  useEffect(load, [modelId]);
  useEffect(() => { if (job?.status === "succeeded") load(); }, [job?.status]);

  async function queue(kind: JobKind, params: Record<string, unknown>) {
    const { data, error } = await api.POST("/api/jobs", { body: { kind, params: { model_version_id: modelId, ...params } } });
    if (data) setJobId(data.id); else setError(errorMessage(error, "Could not queue the job"));
  }

  if (!model) return error ? <p role="alert" className="error">{error}</p> : <p className="muted">Loading…</p>;
  const gold = (model.metrics as Record<string, any>).gold as Record<string, unknown> | null | undefined;
  const latency = (model.metrics as Record<string, any>).latency as Record<string, number> | undefined;
  const events = (gold?.events ?? []) as GoldEvent[];
  return (
    <>
      <h1>{model.version} <span className={`pill status-${model.status}`}>{statusText(model)}</span></h1>
      {model.job_id !== null && (
        <p className="muted">Registered by <Link to="/engineer/jobs">job #{model.job_id}</Link>
          {model.parent ? <> from {model.parent}</> : null}</p>
      )}
      {error && <p role="alert" className="error">{error}</p>}
      <section className="card">
        <h2>Lineage</h2>
        <dl className="facts lineage">
          <dt>Mode</dt><dd>{model.mode}</dd>
          <dt>Family</dt><dd>{model.kind}</dd>
          <dt>Threshold / delay</dt><dd>{fmt(model.threshold)} / {model.delay_ms} ms</dd>
          <dt>Needs</dt><dd className="needs">{model.inputs.join(", ")}{model.keypoints_only ? " (can be a robot's fallback)" : ""}</dd>
          {Object.entries(model.lineage).map(([k, v]) => (<Fragment key={k}><dt>{k}</dt><dd>{fmt(v)}</dd></Fragment>))}
          <dt>sha256</dt><dd><code>{model.sha256}</code></dd>
        </dl>
      </section>
      <section className="card">
        <h2>Gold set evaluation</h2>
        {gold ? (
          <>
            <p className="muted">Real URFD / labelled recordings with split “test”: {fmt((gold.sequences as string[])?.length)} recordings, {fmt(gold.frames)} frames{gold.generated_data ? " (includes GENERATED data)" : ""}.</p>
            {gate?.split && <GoldSplitLine split={gate.split} />}
            <div className="table-wrap">
              <table className="table" aria-label="Table 3">
                <thead><tr>{TABLE3.map((k) => <th key={k} title={metricName(k)}>{k}</th>)}</tr></thead>
                <tbody><tr>{TABLE3.map((k) => <td key={k}>{fmt(gold[k])}</td>)}</tr></tbody>
              </table>
            </div>
            {latency && <p>Per-frame latency: p50 {fmt(latency.p50_ms, 2)} ms, p95 {fmt(latency.p95_ms, 2)} ms.</p>}
            <h3>Per recording</h3>
            <table className="table" aria-label="Events">
              <thead><tr><th>Recording</th><th>Kind</th><th>Alarms</th><th>Detected</th><th>False alarm</th><th>Time to alarm (s)</th></tr></thead>
              <tbody>{events.map((e) => (
                <tr key={e.sequence} className={e.kind === "fall" && !e.detected ? "missed" : ""}>
                  <td>{e.sequence}</td><td>{e.kind}</td><td>{e.alarms}</td><td>{fmt(e.detected)}</td><td>{fmt(e.false_alarm)}</td><td>{fmt(e.time_to_alarm_s, 2)}</td>
                </tr>))}</tbody>
            </table>
            <div className="plots">
              {model.plots.map((p) => <img key={p} alt={`plot ${p}`} src={`/api/models/${model.id}/plots/${p}`} />)}
            </div>
          </>
        ) : <p>Not evaluated on the gold set yet.</p>}
        <p>
          <button type="button" onClick={() => queue("evaluate", {})}>Evaluate on the gold set</button>{" "}
          <button type="button" onClick={() => queue("rethreshold", {})}>Re-choose threshold and delay</button>
        </p>
        {job && <JobProgress job={job} />}
        {job?.status === "failed" && <p role="alert" className="error">{job.message}</p>}
      </section>
      <WhatIf modelId={model.id} threshold={model.threshold} delayMs={model.delay_ms} />
      <Promote modelId={model.id} version={model.version} needs={model.inputs} gate={gate} onDone={load} />
    </>
  );
}

function GoldSplitLine({ split }: { split: GoldSplit }) {
  const { text, clean } = goldSplitText(split);
  return <p aria-label="Gold set and training" className={clean ? "split-clean" : "error"}>{text}</p>;
}

function WhatIf({ modelId, threshold, delayMs }: { modelId: number; threshold: number; delayMs: number }) {
  const [t, setT] = useState(String(threshold));
  const [d, setD] = useState(String(delayMs));
  const [jobId, setJobId] = useState<number | null>(null);
  const [error, setError] = useState<string | null>(null);
  const job = useJob(jobId);
  async function run(event: FormEvent) {
    event.preventDefault();
    const { data, error } = await api.POST("/api/jobs", {
      body: { kind: "whatif", params: { model_version_id: modelId, threshold: Number(t), delay_ms: Number(d) } },
    });
    if (data) setJobId(data.id); else setError(errorMessage(error, "Could not start the replay"));
  }
  const result = job?.status === "succeeded" ? (job.result as Record<string, any>) : null;
  const rows = ["alarms", "falls_detected", "adl_false_alarms", "frame_recall", "median_time_to_alarm_s"];
  return (
    <section className="card">
      <h2>What-if replay</h2>
      <form className="filters" onSubmit={run} aria-label="What-if">
        <label>Threshold <input name="threshold" type="number" step="any" min="0" max="1" value={t} onChange={(e) => setT(e.target.value)} /></label>
        <label>Delay (ms) <input name="delay_ms" type="number" step="10" min="0" max="10000" value={d} onChange={(e) => setD(e.target.value)} /></label>
        <button type="submit">Replay labelled recordings</button>
      </form>
      {error && <p role="alert" className="error">{error}</p>}
      {job && !result && <JobProgress job={job} />}
      {job?.status === "failed" && <p role="alert" className="error">{job.message}</p>}
      {result && (
        <table className="table" aria-label="What-if result">
          <thead><tr><th /><th>Current</th><th>What-if</th><th>Change</th></tr></thead>
          <tbody>{rows.map((k) => (
            <tr key={k} data-metric={k}><td>{metricName(k)}</td><td>{fmt(result.baseline[k])}</td><td>{fmt(result.candidate[k])}</td><td>{fmt(result.change[k])}</td></tr>
          ))}</tbody>
        </table>
      )}
    </section>
  );
}

/** The robots a promotion of this scope would reach. */
export function inScope(robots: FleetRobot[], scope: "robot" | "ward" | "fleet", target: string): FleetRobot[] {
  if (scope === "fleet") return robots;
  return robots.filter((r) => (scope === "robot" ? r.id === target : r.ward === target));
}

/** What a promotion of this scope reaches, in words, for the confirmation step. */
export function scopeText(scope: "robot" | "ward" | "fleet", target: string, robots: FleetRobot[]): string {
  const where = scope === "fleet" ? "the whole fleet" : scope === "ward" ? `ward ${target}` : `robot ${target}`;
  const ids = robots.map((r) => r.id).join(", ");
  return `${where}: ${robots.length} robot${robots.length === 1 ? "" : "s"}${ids ? ` (${ids})` : ""}`;
}

function Promote({ modelId, version, needs, gate, onDone }: { modelId: number; version: string; needs: string[]; gate: GateReport | null; onDone: () => void }) {
  // The narrowest scope by default, and nothing happens before the engineer confirms it.
  const [scope, setScope] = useState<"robot" | "ward" | "fleet">("robot");
  const [confirming, setConfirming] = useState<"promotion" | "shadow" | null>(null);
  const [target, setTarget] = useState("");
  const [canary, setCanary] = useState("");
  const [comment, setComment] = useState("");
  const [onlyCapable, setOnlyCapable] = useState(false);
  const [robots, setRobots] = useState<FleetRobot[] | null>(null);
  const [result, setResult] = useState<Deployment | null>(null);
  const [error, setError] = useState<string | null>(null);
  const loadRobots = () => {
    void api.GET("/api/fleet", { params: { query: { model_id: modelId } } }).then(({ data }) => data && setRobots(data));
  };
  useEffect(loadRobots, [modelId]);
  const shown = robots ? inScope(robots, scope, target) : [];
  const refused = shown.filter((r) => r.qualifies === false);
  const reached = onlyCapable && scope !== "robot" ? shown.filter((r) => r.qualifies !== false) : shown;
  const wards = [...new Set((robots ?? []).map((r) => r.ward))].sort();
  const chosen = scope === "fleet" || target !== "";
  const changeScope = (next: typeof scope) => { setScope(next); setTarget(""); setCanary(""); setConfirming(null); };
  async function send(shadow: boolean) {
    setError(null);
    setConfirming(null);
    const body = { scope, target: target || null, comment: comment || null, only_capable: onlyCapable };
    const response = shadow
      ? await api.POST("/api/models/{model_id}/shadow", { params: { path: { model_id: modelId } }, body })
      : await api.POST("/api/models/{model_id}/promote", {
          params: { path: { model_id: modelId } }, body: { ...body, canary_robot_id: canary || null },
        });
    if (response.data) { setResult(response.data); onDone(); }
    else setError(errorMessage(response.error, "Promotion refused"));
    loadRobots();
  }
  return (
    <section className="card">
      <h2>Promote</h2>
      {gate && (
        <div aria-label="Gate" className={gate.passed ? "gate gate-pass" : "gate gate-fail"}>
          <strong>Gate: {gate.passed ? "passed" : "blocked"}</strong>
          <ul>{gate.checks.map((c) => (
            <li key={c.name} className={c.passed ? "ok" : "fail"}>{c.passed ? "✓" : "✗"} {c.name}: {c.detail}</li>
          ))}</ul>
          {(gate.warnings ?? []).map((w) => <p key={w} className="warning">⚠ {w}</p>)}
        </div>
      )}
      <form className="filters" onSubmit={(e) => { e.preventDefault(); setConfirming("promotion"); }} aria-label="Promote">
        <label>Scope
          <select name="scope" value={scope} onChange={(e) => changeScope(e.target.value as typeof scope)}>
            <option value="robot">one robot</option><option value="ward">a ward</option><option value="fleet">the fleet</option>
          </select>
        </label>
        {scope === "robot" && (
          <label>Robot
            <select name="target" aria-label="Robot" value={target} onChange={(e) => { setTarget(e.target.value); setConfirming(null); }}>
              <option value="">choose…</option>
              {(robots ?? []).map((r) => <option key={r.id} value={r.id}>{r.id} ({r.ward})</option>)}
            </select>
          </label>
        )}
        {scope === "ward" && (
          <label>Ward
            <select name="target" aria-label="Ward" value={target} onChange={(e) => { setTarget(e.target.value); setConfirming(null); }}>
              <option value="">choose…</option>
              {wards.map((w) => <option key={w} value={w}>{w}</option>)}
            </select>
          </label>
        )}
        {scope !== "robot" && (
          <label>Canary robot
            <select name="canary" aria-label="Canary robot" value={canary} onChange={(e) => setCanary(e.target.value)}>
              <option value="">first robot of the scope</option>
              {reached.map((r) => <option key={r.id} value={r.id}>{r.id}</option>)}
            </select>
          </label>
        )}
        <label>Comment <input name="comment" value={comment} onChange={(e) => setComment(e.target.value)} /></label>
        {scope !== "robot" && (
          <label className="inline">
            <input name="only_capable" type="checkbox" checked={onlyCapable} onChange={(e) => setOnlyCapable(e.target.checked)} />
            {" "}leave out robots that cannot feed it
          </label>
        )}
        <button className="primary" type="submit" disabled={!gate?.passed || !chosen}>Sign off and promote</button>
        <button type="button" disabled={!chosen} onClick={() => setConfirming("shadow")}>Run in shadow mode</button>
      </form>
      {confirming === "promotion" && (
        <ConfirmDialog label="Confirm promotion" confirm="Confirm promotion"
          onConfirm={() => void send(false)} onBack={() => setConfirming(null)}>
          <p>
            Promote <strong>{version}</strong> to {scopeText(scope, target, reached)}
            {scope !== "robot" ? `, starting with canary ${canary || reached[0]?.id || "–"}` : ""}? These
            robots then detect falls with this model.
          </p>
        </ConfirmDialog>
      )}
      {confirming === "shadow" && (
        <ConfirmDialog label="Confirm shadow run" confirm="Start the shadow run"
          onConfirm={() => void send(true)} onBack={() => setConfirming(null)}>
          <p>
            Run <strong>{version}</strong> in shadow mode on {scopeText(scope, target, reached)}? These
            robots run it beside the model they detect falls with; it raises no alarm, and where the
            two disagree the frames are queued for review.
          </p>
        </ConfirmDialog>
      )}
      <h3>Robots in the scope</h3>
      <p className="muted">
        The model needs {needs.join(", ")} in every frame; a robot that cannot feed it is refused
        {scope !== "robot" ? " (the whole promotion, unless robots that cannot are left out)" : ""}.
      </p>
      {robots === null ? <p className="muted">Loading…</p> : shown.length === 0 ? <p className="empty">No robot in this scope.</p> : (
        <table className="table" aria-label="Qualifying robots">
          <thead><tr><th>Robot</th><th>Ward</th><th>Inputs</th><th>Qualifies</th><th>Current target</th><th>Fallback</th></tr></thead>
          <tbody>{shown.map((r) => (
            <tr key={r.id} data-robot={r.id} className={r.qualifies ? "" : "refused"}>
              <td>{r.id}</td><td>{r.ward}</td><td>{inputsText(r)}</td>
              <td>{r.qualifies
                ? <span className="pill qualifies">yes</span>
                : <span className="pill refused">no: lacks {r.missing_inputs.join(", ")}</span>}</td>
              <td>{r.target_version ?? "–"}</td><td>{r.fallback_version ?? "–"}</td>
            </tr>))}</tbody>
        </table>
      )}
      {refused.length > 0 && <p className="warning" aria-label="Refused robots">⚠ {refused.length} of {shown.length} robots cannot feed this model: {refused.map((r) => r.id).join(", ")}</p>}
      {error && <p role="alert" className="error">{error}</p>}
      {result && <p role="status">Deployment {result.id}: {result.status}{result.shadow ? " (shadow)" : ""}{result.rollout?.canary && result.status === "canary" ? `, canary ${String(result.rollout.canary)}` : ""}{result.rollout?.skipped ? `; left out: ${Object.keys(result.rollout.skipped as Record<string, string>).join(", ")}` : ""}.</p>}
    </section>
  );
}
