// "Audio paused" as IEC 60601-1-8 describes it: the nurse silences the tone for a fixed time;
// the visual alarm stays, and the pause lifts itself when it runs out or a new Emergency arrives.
import type { Alarm } from "../api/types";
import { unacknowledgedEmergencies } from "./alarmBoard";

export const AUDIO_PAUSE_MS = 2 * 60_000;

export interface AudioPause {
  /** Epoch ms when the pause runs out. */
  until: number;
  /** The Emergencies calling for attention when the nurse paused: only these stay silent. */
  silenced: ReadonlySet<string>;
}

/** An Emergency's identity across its provisional (not yet stored) and stored versions. */
const identity = (alarm: Alarm): string => alarm.key ?? `id:${alarm.id}`;

export function pauseAudio(alarms: Iterable<Alarm>, now: number): AudioPause {
  return { until: now + AUDIO_PAUSE_MS, silenced: new Set(unacknowledgedEmergencies(alarms).map(identity)) };
}

/** The pause still holds: not run out, and no Emergency calls that was not silenced. */
export function pauseHolds(pause: AudioPause | null, alarms: Iterable<Alarm>, now: number): boolean {
  if (!pause || now >= pause.until) return false;
  return unacknowledgedEmergencies(alarms).every((a) => pause.silenced.has(identity(a)));
}

/** "1:42" left of a pause. */
export function pauseLeft(pause: AudioPause, now: number): string {
  const s = Math.max(0, Math.ceil((pause.until - now) / 1000));
  return `${Math.floor(s / 60)}:${String(s % 60).padStart(2, "0")}`;
}
