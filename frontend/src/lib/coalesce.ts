/** `run` at most once per `intervalMs`: a trigger while idle runs it at once, triggers within
 * the interval after a run make one more run when the interval is up (so the last news is
 * never missed). A thousand robots reconnecting push fleet news with every commit; each page
 * reloads the fleet a couple of times a second, not with every push. */
export function coalesce(run: () => void, intervalMs: number): { trigger: () => void; stop: () => void } {
  let lastRun = -Infinity;
  let timer: ReturnType<typeof setTimeout> | null = null;
  const fire = () => {
    timer = null;
    lastRun = Date.now();
    run();
  };
  return {
    trigger: () => {
      if (timer !== null) return;
      const wait = lastRun + intervalMs - Date.now();
      if (wait <= 0) fire();
      else timer = setTimeout(fire, wait);
    },
    stop: () => {
      if (timer !== null) clearTimeout(timer);
      timer = null;
    },
  };
}
