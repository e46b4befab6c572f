import { useEffect, useLayoutEffect, useState } from "react";
import { alarmSound, type AudioState } from "../lib/alarmSound";

/** Plays the emergency tone while `required`; returns the audio state and the unlock action. */
export function useAlarmSound(required: boolean): { state: AudioState; unlock(): Promise<boolean> } {
  const [state, setState] = useState<AudioState>(alarmSound.state);
  useEffect(() => alarmSound.subscribe(setState), []);
  // A layout effect: the tone starts in the same task that puts the alarm on the board, not
  // after the browser has painted it.
  useLayoutEffect(() => {
    if (required && state === "ready") alarmSound.start();
    if (!required && state === "playing") alarmSound.stop();
  }, [required, state]);
  useEffect(() => () => alarmSound.stop(), []);
  return { state, unlock: () => alarmSound.unlock() };
}
