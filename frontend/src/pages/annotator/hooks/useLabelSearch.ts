import { useCallback, useMemo, useRef, useState, type ChangeEvent, type KeyboardEvent } from "react";
import { moveActive, searchChoice, searchLabels } from "../timelineLogic";
import type { TaxonomyLabel } from "../types";

/** The label search box: up to 8 matches, ↓ ↑ to choose one, Enter (or a click) applies only a
 * chosen label; Enter without a choice says how many match instead. */
export function useLabelSearch(
  labels: TaxonomyLabel[],
  applyLabel: (key: string) => Promise<void> | void,
  say: (message: string) => void,
) {
  const [query, setQuery] = useState("");
  const [activeMatch, setActiveMatch] = useState<number | null>(null);
  const box = useRef<HTMLInputElement>(null);
  const matches = useMemo(() => searchLabels(labels, query).slice(0, 8), [labels, query]);

  const choose = useCallback(
    (key: string) => {
      void applyLabel(key);
      setQuery("");
      setActiveMatch(null);
    },
    [applyLabel],
  );

  const onChange = useCallback((e: ChangeEvent<HTMLInputElement>) => {
    setQuery(e.target.value);
    setActiveMatch(null);
  }, []);

  const onKeyDown = useCallback(
    (e: KeyboardEvent<HTMLInputElement>) => {
      if (e.key === "ArrowDown" || e.key === "ArrowUp") {
        e.preventDefault();
        setActiveMatch((a) => moveActive(a, e.key === "ArrowDown" ? 1 : -1, matches.length));
      } else if (e.key === "Enter") {
        const choice = searchChoice(matches, activeMatch);
        if (!choice) {
          say(
            matches.length === 0
              ? `No label matches “${query}”`
              : `${matches.length} labels match “${query}”: choose one with ↓ ↑ and Enter, or click it`,
          );
          return;
        }
        choose(choice.key);
        e.currentTarget.blur();
      } else if (e.key === "Escape") e.currentTarget.blur();
    },
    [matches, activeMatch, query, choose, say],
  );

  const focus = useCallback(() => box.current?.focus(), []);

  return { box, query, matches, activeMatch, onChange, onKeyDown, choose, focus };
}
