import type { ReactNode } from "react";

/** The confirmation step of an action that changes what robots run (promotion, shadow run,
 * rollback): nothing happens before the engineer confirms; "Back" changes nothing. */
export function ConfirmDialog({ label, confirm, onConfirm, onBack, disabled = false, children }: {
  label: string;
  confirm: string;
  onConfirm: () => void;
  onBack: () => void;
  disabled?: boolean;
  children: ReactNode;
}) {
  return (
    <div className="card confirm" role="dialog" aria-label={label}>
      {children}
      <button type="button" className="primary" disabled={disabled} onClick={onConfirm}>{confirm}</button>
      <button type="button" onClick={onBack}>Back</button>
    </div>
  );
}
