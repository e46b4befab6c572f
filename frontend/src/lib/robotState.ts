// What a robot did about its decisions (its behaviour state, as it reported it), in a nurse's
// words on the nurse pages and as the state's name with its reason for engineers.
import { clockTime } from "./time";

export type RobotState = "transporting" | "paused" | "emergency_stop" | "detection_degraded";

export const ROBOT_STATE_WORDS: Record<RobotState, string> = {
  emergency_stop: "Robot stopped, waiting for help",
  paused: "Robot paused",
  transporting: "Robot driving",
  detection_degraded: "Detection degraded – robot slowed or stopped",
};

/** "Robot stopped, waiting for help since 12:03:05" (null: the robot has not said). */
export function robotStateText(state: RobotState | null | undefined, since: string | null | undefined): string | null {
  if (!state) return null;
  const words = ROBOT_STATE_WORDS[state] ?? state;
  return since ? `${words} since ${clockTime(since)}` : words;
}
