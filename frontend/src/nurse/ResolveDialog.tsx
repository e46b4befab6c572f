import { useEffect, useState, type FormEvent } from "react";
import type { Alarm, FalseAlarmReason, Verdict } from "../api/types";
import { KIND_LABEL } from "../lib/alarmBoard";
import { robotLabel } from "../lib/dispositions";
import { REASON_LABEL, VERDICT_LABEL } from "./labels";

export interface Resolution {
  verdict: Verdict;
  reason?: FalseAlarmReason;
  comment?: string;
}

interface Props {
  alarm: Alarm;
  error: string | null;
  busy: boolean;
  onSubmit(resolution: Resolution): void;
  onCancel(): void;
}

export function ResolveDialog({ alarm, error, busy, onSubmit, onCancel }: Props) {
  const [verdict, setVerdict] = useState<Verdict | null>(null);
  const [reason, setReason] = useState<FalseAlarmReason | null>(null);
  const [comment, setComment] = useState("");
  useEffect(() => {
    const onKey = (event: KeyboardEvent) => event.key === "Escape" && onCancel();
    window.addEventListener("keydown", onKey);
    return () => window.removeEventListener("keydown", onKey);
  }, [onCancel]);
  const ready = verdict !== null && (verdict !== "false_alarm" || reason !== null);

  function submit(event: FormEvent) {
    event.preventDefault();
    if (!verdict || !ready) return;
    onSubmit({
      verdict,
      reason: verdict === "false_alarm" ? (reason ?? undefined) : undefined,
      comment: comment.trim() || undefined,
    });
  }

  return (
    <div className="modal-backdrop" role="presentation">
      <form className="card modal" role="dialog" aria-label="Resolve alarm" onSubmit={submit}>
        <h2>Resolve {KIND_LABEL[alarm.kind].toLowerCase()} alarm #{alarm.id}</h2>
        <p className="muted">Robot {robotLabel(alarm)} · patient {alarm.patient ?? "–"}</p>
        <fieldset>
          <legend>Verdict</legend>
          {(Object.keys(VERDICT_LABEL) as Verdict[]).map((v) => (
            <label key={v} className="choice">
              <input type="radio" name="verdict" value={v} checked={verdict === v}
                onChange={() => setVerdict(v)} />
              {VERDICT_LABEL[v]}
            </label>
          ))}
        </fieldset>
        {verdict === "false_alarm" && (
          <fieldset>
            <legend>What was the patient doing?</legend>
            {(Object.keys(REASON_LABEL) as FalseAlarmReason[]).map((r) => (
              <label key={r} className="choice">
                <input type="radio" name="reason" value={r} checked={reason === r}
                  onChange={() => setReason(r)} />
                {REASON_LABEL[r]}
              </label>
            ))}
          </fieldset>
        )}
        <label>
          Comment (optional)
          <textarea name="comment" rows={2} maxLength={1000} value={comment}
            onChange={(e) => setComment(e.target.value)} />
        </label>
        {!ready && (
          <p className="muted" data-testid="resolve-hint">
            {verdict === null
              ? "Choose a verdict to resolve."
              : "Choose what the patient was doing: a false alarm needs a reason, so the model learns from it."}
          </p>
        )}
        {error && <p role="alert" className="error">{error}</p>}
        <div className="actions">
          <button type="button" onClick={onCancel}>Cancel</button>
          <button type="submit" className="primary" disabled={!ready || busy}>Resolve</button>
        </div>
      </form>
    </div>
  );
}
