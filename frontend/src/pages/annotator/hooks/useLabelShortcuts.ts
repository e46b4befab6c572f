import { useEffect } from "react";
import type { TaxonomyLabel } from "../types";
import type { TimelineState } from "./useTimeline";

interface Actions {
  timeline: TimelineState;
  quick: TaxonomyLabel[];
  applyLabel: (key: string) => Promise<void> | void;
  undoRedo: (isUndo: boolean) => Promise<void> | void;
  submit: () => Promise<void> | void;
  deleteSelected: () => Promise<void> | void;
  focusSearch: () => void;
  toggleHelp: () => void;
  closeHelp: () => void;
  toggleRgb: () => void;
  toggleBlur: () => void;
  mayUnblur: boolean;
}

/** The label page's keyboard (listed in ShortcutsHelp); ignored while typing in a field. */
export function useLabelShortcuts(a: Actions) {
  const { timeline: t, quick, applyLabel, undoRedo, submit, deleteSelected } = a;
  const { focusSearch, toggleHelp, closeHelp, toggleRgb, toggleBlur, mayUnblur } = a;
  const { togglePlay, stepBy, toStart, toEnd, markIn, markOut, clearMarks, changeSpeed } = t;
  useEffect(() => {
    const onKey = (event: KeyboardEvent) => {
      const typing = event.target instanceof HTMLInputElement || event.target instanceof HTMLTextAreaElement
        || event.target instanceof HTMLSelectElement;
      if (typing) return;
      const ctrl = event.ctrlKey || event.metaKey;
      const key = event.key;
      let handled = true;
      if (ctrl && key.toLowerCase() === "z") void undoRedo(!event.shiftKey);
      else if (ctrl && key.toLowerCase() === "y") void undoRedo(false);
      else if (ctrl && key === "Enter") void submit();
      else if (ctrl) handled = false;
      else if (key === " ") togglePlay();
      else if (key === "ArrowRight") stepBy(event.shiftKey ? 10 : 1);
      else if (key === "ArrowLeft") stepBy(event.shiftKey ? -10 : -1);
      else if (key === "Home") toStart();
      else if (key === "End") toEnd();
      else if (key === "i" || key === "I") markIn();
      else if (key === "o" || key === "O") markOut();
      else if (/^[1-9]$/.test(key) && quick[Number(key) - 1]) void applyLabel(quick[Number(key) - 1].key);
      else if (key === "/") focusSearch();
      else if (key === "?") toggleHelp();
      else if (key === "Escape") { clearMarks(); closeHelp(); }
      else if (key === "Delete" || key === "Backspace") void deleteSelected();
      else if (key === "[") changeSpeed(-1);
      else if (key === "]") changeSpeed(1);
      else if (key === "v" || key === "V") toggleRgb();
      else if ((key === "b" || key === "B") && mayUnblur) toggleBlur();
      else handled = false;
      if (handled) event.preventDefault();
    };
    window.addEventListener("keydown", onKey);
    return () => window.removeEventListener("keydown", onKey);
  }, [quick, applyLabel, undoRedo, submit, deleteSelected, focusSearch, toggleHelp, closeHelp, toggleRgb,
    toggleBlur, mayUnblur, togglePlay, stepBy, toStart, toEnd, markIn, markOut, clearMarks, changeSpeed]);
}
