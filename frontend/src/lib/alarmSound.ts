// The emergency tone, generated with WebAudio (no audio files). Browsers keep audio locked until
// the page receives a click, so the console asks for a 'start shift' click first.

export type AudioState = "locked" | "ready" | "playing";

const BEEP_HZ = [988, 784]; // a falling two-tone, repeated
const BEEP_S = 0.18;
const REPEAT_MS = 1200;

export class AlarmSound {
  private context: AudioContext | null = null;
  private timer: number | undefined;
  private listeners = new Set<(state: AudioState) => void>();
  state: AudioState = "locked";

  subscribe(listener: (state: AudioState) => void): () => void {
    this.listeners.add(listener);
    listener(this.state);
    return () => this.listeners.delete(listener);
  }

  /** Must run inside a click handler. Resolves true when the audio context is running. */
  async unlock(): Promise<boolean> {
    this.context ??= new AudioContext();
    if (this.context.state !== "running") {
      try {
        await this.context.resume();
      } catch {
        return false;
      }
    }
    const running = this.context.state === "running";
    if (running && this.state === "locked") this.setState("ready");
    return running;
  }

  /** Start repeating the tone (no-op while locked or already playing). */
  start(): void {
    if (this.state !== "ready" || !this.context) return;
    this.beep();
    this.timer = window.setInterval(() => this.beep(), REPEAT_MS);
    this.setState("playing");
  }

  stop(): void {
    window.clearInterval(this.timer);
    this.timer = undefined;
    if (this.state === "playing") this.setState("ready");
  }

  private beep(): void {
    const ctx = this.context;
    if (!ctx) return;
    const t0 = ctx.currentTime;
    BEEP_HZ.forEach((hz, i) => {
      const osc = ctx.createOscillator();
      const gain = ctx.createGain();
      osc.type = "square";
      osc.frequency.value = hz;
      const start = t0 + i * (BEEP_S + 0.04);
      gain.gain.setValueAtTime(0.0001, start);
      gain.gain.exponentialRampToValueAtTime(0.25, start + 0.01);
      gain.gain.exponentialRampToValueAtTime(0.0001, start + BEEP_S);
      osc.connect(gain).connect(ctx.destination);
      osc.start(start);
      osc.stop(start + BEEP_S + 0.02);
    });
  }

  private setState(state: AudioState): void {
    this.state = state;
    for (const listener of this.listeners) listener(state);
  }
}

export const alarmSound = new AlarmSound();
