/** Reconnect delay: 0.5 s doubling to at most 8 s, with up to 20 % jitter so tablets spread out. */
export function reconnectDelayMs(attempt: number, random: () => number = Math.random): number {
  const base = Math.min(500 * 2 ** Math.max(0, attempt), 8000);
  return Math.round(base * (1 + 0.2 * random()));
}
