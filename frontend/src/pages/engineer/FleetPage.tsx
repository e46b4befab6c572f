import { useEffect, useState } from "react";
import { api, errorMessage } from "../../api/client";
import { clockTime } from "../../lib/time";
import { ConfirmDialog } from "./ConfirmDialog";
import type { Deployment, FleetRobot } from "./types";
import { useFleetPush } from "./useFleetPush";

/** The fleet's changes are pushed (useFleetPush); this slow poll is only a fallback, for news
 * the socket could not bring (a change made by the worker, e.g. an automatic rollback, or on a
 * replica without Redis). */
export const FLEET_FALLBACK_POLL_MS = 30_000;

/** "keypoints, depth, floor" (or "keypoints (not reported)" for an agent that did not say). */
export function inputsText(robot: Pick<FleetRobot, "inputs" | "inputs_reported">): string {
  return robot.inputs.join(", ") + (robot.inputs_reported ? "" : " (not reported)");
}

export function FleetPage() {
  const [robots, setRobots] = useState<FleetRobot[] | null>(null);
  const [deployments, setDeployments] = useState<Deployment[]>([]);
  const [error, setError] = useState<string | null>(null);
  // The deployment the engineer is about to roll back, and the reason they give (required).
  const [rollingBack, setRollingBack] = useState<Deployment | null>(null);
  const [reason, setReason] = useState("");
  const load = () => {
    void api.GET("/api/fleet").then(({ data, error }) => {
      if (data) setRobots(data); else setError(errorMessage(error, "Could not load the fleet"));
    });
    void api.GET("/api/deployments").then(({ data }) => data && setDeployments(data));
  };
  useEffect(() => {
    load();
    const timer = setInterval(load, FLEET_FALLBACK_POLL_MS);
    return () => clearInterval(timer);
  }, []);
  useFleetPush(load);

  const askRollback = (deployment: Deployment) => { setRollingBack(deployment); setReason(""); };
  async function act(id: number, action: "rollback" | "advance" | "approve") {
    setError(null);
    const path = { params: { path: { deployment_id: id } } };
    if (action === "rollback") setRollingBack(null);
    const response =
      action === "rollback" ? await api.POST("/api/deployments/{deployment_id}/rollback", { ...path, body: { reason: reason.trim() } })
      : action === "advance" ? await api.POST("/api/deployments/{deployment_id}/advance", path)
      : await api.POST("/api/deployments/{deployment_id}/approve", path);
    if (response.error) setError(errorMessage(response.error, `Could not ${action}`));
    load();
  }

  return (
    <>
      <h1>Fleet</h1>
      {error && <p role="alert" className="error">{error}</p>}
      {robots === null ? <p className="muted">Loading…</p> : (
        <table className="table" aria-label="Fleet">
          <thead><tr><th>Robot</th><th>Ward</th><th>Connected</th><th>Behaviour</th><th>Inputs</th><th>Target version</th><th>Running version</th><th>Fallback</th><th>Shadow</th><th /></tr></thead>
          <tbody>{robots.map((r) => (
            <tr key={r.id} className={r.in_sync ? "" : "out-of-sync"} data-robot={r.id}>
              <td>{r.id}</td><td>{r.ward}</td><td>{r.connected ? "yes" : "no"}</td>
              <td className={`behaviour robot-${r.behaviour_state ?? "unknown"}`} title={r.behaviour_reason ?? ""} data-testid="behaviour">
                {r.behaviour_state ? `${r.behaviour_state.replace("_", " ")} since ${clockTime(r.behaviour_since)}` : "–"}
              </td>
              <td className="inputs">{inputsText(r)}</td>
              <td>{r.target_version ?? "–"}{r.target_feedable ? "" : <span className="pill refused" title="the robot lacks an input this model needs"> cannot feed</span>}</td>
              <td>{r.running_version ?? "–"}</td>
              <td className="fallback">{r.fallback_version ?? "–"}</td>
              <td>{r.shadow_version ?? "–"}</td>
              <td>
                {r.in_sync ? "in sync" : !r.connected ? "pending: robot offline"
                  : r.running_version === r.target_version
                    ? (r.running_sha256 ? "not the registry's file" : "file not verified (no sha256 reported)")
                    : "switching…"}
                {r.detection_degraded && <> <span className="pill kind-detection_degraded">detection degraded</span></>}
              </td>
            </tr>))}</tbody>
        </table>
      )}
      <h2>Deployments</h2>
      <table className="table" aria-label="Deployments">
        <thead><tr><th>#</th><th>Model</th><th>Scope</th><th>Status</th><th>Robots</th><th>Nurse-rejected alarms</th><th>Note</th><th>Actions</th></tr></thead>
        <tbody>{deployments.map((d) => {
          const live = d.status === "canary" || d.status === "active";
          return (
            <tr key={d.id}>
              <td>{d.id}</td><td>{d.model_version}{d.shadow ? " (shadow)" : ""}</td>
              <td>{d.scope}{d.target ? ` ${d.target}` : ""}</td>
              <td><span className={`pill deploy-${d.status}`}>{d.status}</span></td>
              <td>{((d.rollout?.assigned as string[] | undefined) ?? []).join(", ")}{d.status === "canary" ? ` (canary ${String(d.rollout?.canary)})` : ""}</td>
              <td>{d.shadow ? "–" : `${d.alarms_rejected ?? 0} of ${d.alarms_judged ?? 0}`}</td>
              <td>{d.rollback_reason ?? d.comment ?? ""}</td>
              <td>
                {d.status === "pending_approval" && <button type="button" onClick={() => act(d.id, "approve")}>Approve</button>}
                {d.status === "canary" && <button type="button" onClick={() => act(d.id, "advance")}>Roll out to all</button>}
                {live && <button type="button" onClick={() => askRollback(d)}>Roll back</button>}
              </td>
            </tr>
          );
        })}</tbody>
      </table>
      {rollingBack && (
        <ConfirmDialog label="Confirm rollback" confirm="Confirm rollback" disabled={reason.trim() === ""}
          onConfirm={() => void act(rollingBack.id, "rollback")} onBack={() => setRollingBack(null)}>
          <p>
            Roll back deployment {rollingBack.id}, <strong>{rollingBack.model_version}</strong>
            {rollingBack.shadow ? " (shadow)" : ""} on {((rollingBack.rollout?.assigned as string[] | undefined) ?? []).join(", ") || "no robot yet"}?
            Each of these robots gets back the model it had before.
          </p>
          <label>Reason (kept with the deployment)
            <textarea name="reason" required rows={2} maxLength={2000} value={reason}
              onChange={(e) => setReason(e.target.value)} />
          </label>
        </ConfirmDialog>
      )}
    </>
  );
}
