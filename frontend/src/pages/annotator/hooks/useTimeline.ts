import { useCallback, useEffect, useRef, useState } from "react";
import type { LabellingVideo } from "../types";
import { clampFrame, nextSpeed, playbackAdvance, step } from "../timelineLogic";

/** The playhead: current frame, playback at a speed, and the in/out marks of a new segment. */
export function useTimeline(video: LabellingVideo | null, initialFrame: number) {
  const [frame, setFrame] = useState(initialFrame);
  const [playing, setPlaying] = useState(false);
  const [speed, setSpeed] = useState(1);
  const [inPoint, setInPoint] = useState<number | null>(null);
  const [outPoint, setOutPoint] = useState<number | null>(null);
  const frameCount = video?.frame_count ?? 0;
  const frameRef = useRef(frame); // read by key handlers, never stale between renders
  frameRef.current = frame;

  // Playback: advance by elapsed time x fps x speed, carrying fractions of a frame.
  useEffect(() => {
    if (!playing || !video) return;
    let last = performance.now();
    let carry = 0;
    let handle = 0;
    const tick = (now: number) => {
      carry += playbackAdvance(now - last, video.fps, speed);
      last = now;
      const whole = Math.floor(carry);
      if (whole > 0) {
        carry -= whole;
        setFrame((f) => {
          const next = f + whole;
          if (next >= video.frame_count - 1) setPlaying(false);
          return clampFrame(next, video.frame_count);
        });
      }
      handle = requestAnimationFrame(tick);
    };
    handle = requestAnimationFrame(tick);
    return () => cancelAnimationFrame(handle);
  }, [playing, speed, video]);

  const togglePlay = useCallback(() => setPlaying((p) => !p), []);
  const stepBy = useCallback((delta: number) => setFrame((f) => step(f, delta, frameCount)), [frameCount]);
  const seek = useCallback((f: number) => setFrame(clampFrame(f, frameCount)), [frameCount]);
  const toStart = useCallback(() => setFrame(0), []);
  const toEnd = useCallback(() => setFrame(Math.max(frameCount - 1, 0)), [frameCount]);
  const changeSpeed = useCallback((direction: 1 | -1) => setSpeed((s) => nextSpeed(s, direction)), []);
  const markIn = useCallback(() => setInPoint(frameRef.current), []);
  const markOut = useCallback(() => setOutPoint(frameRef.current), []);
  const clearMarks = useCallback(() => {
    setInPoint(null);
    setOutPoint(null);
  }, []);

  return {
    frame, frameRef, frameCount, playing, speed, inPoint, outPoint,
    togglePlay, stepBy, seek, toStart, toEnd, changeSpeed, markIn, markOut, clearMarks,
  };
}

export type TimelineState = ReturnType<typeof useTimeline>;
