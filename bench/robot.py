"""`make bench-robot`: the robot agent's per-frame cost, MediaPipe speed, outbox replay rate.
Writes bench/results/robot.json.

- frame_p50_ms / frame_p99_ms: one frame through the agent: tracking, depth sampling (a real
  URFD 16-bit depth PNG), features, ONNX inference, threshold and delay filter, outbox write
  (SQLite). Keypoints are GENERATED (vigil.synthetic), the model is the default walking model
  trained on URFD (var/models/default-walking, trained first if missing).
- sustained_hz: frames per second when frames are pushed back to back.
- mediapipe_fps: MediaPipe pose (model_complexity=1) on the shared URFD video, right half.
- outbox_replay_frames_per_s: frames left in the outbox while the backend was away, resent
  and acknowledged by the real backend (uvicorn subprocess, SQLite) after it came back.
Goals (issue 5): frame p99 <= 5 ms; MediaPipe >= 15 frames/s on 2 cores.
"""

from __future__ import annotations

import asyncio
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from robot_agent.client import Backoff, RobotClient
from robot_agent.depth import URFD_FALL_MM_PER_UNIT
from robot_agent.models import ModelManager
from robot_agent.outbox import Outbox
from robot_agent.pipeline import FramePipeline
from robot_agent.sources import Observation
from vigil.datasets.urfd import default_dir
from vigil.runtime import FrameClassifier
from vigil.synthetic import generate_transport

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "robot.json"
MODEL_DIR = ROOT / "var" / "models" / "default-walking"
REPLAY_FRAMES = 20_000


def ensure_model() -> Path:
    if not (MODEL_DIR / "manifest.json").exists():
        subprocess.run([sys.executable, "-m", "worker.training.cli", "train-default", "--out",
                        str(MODEL_DIR)], cwd=ROOT, check=True)  # fmt: skip
    return MODEL_DIR


def frame_times(model_dir: Path, work: Path) -> dict:
    depth_png = sorted((default_dir() / "depth").glob("*.png"))[0]
    depth_image = cv2.imread(str(depth_png), cv2.IMREAD_UNCHANGED)
    manager = ModelManager(work / "models", FrameClassifier.from_dir(model_dir))
    outbox = Outbox(work / "frame-bench.sqlite", max_frames=1_000_000)
    pipeline = FramePipeline(outbox, manager, depth_mm_per_unit=URFD_FALL_MM_PER_UNIT)
    observations: list[Observation] = []
    for seed in range(4):
        transport = generate_transport("walking", seed=seed, duration_s=30, n_people=1)
        offset = len(observations) / 30  # one continuous stream
        for t in range(transport.n_frames):
            observations.append(Observation(offset + t / 30, transport.detections(t), depth_image))
    pipeline.start_transport()
    for obs in observations[:200]:  # warm-up
        pipeline.process(obs)
    pipeline.start_transport()
    times, cpu_times = [], []
    start = time.perf_counter()
    for obs in observations:
        t0, c0 = time.perf_counter(), time.thread_time()
        pipeline.process(obs)
        cpu_times.append(time.thread_time() - c0)
        times.append(time.perf_counter() - t0)
    total = time.perf_counter() - start
    outbox.close()
    ms = np.array(times) * 1000
    cpu_ms = np.array(cpu_times) * 1000
    return {
        # CPU time of the frame loop's thread: what the frame costs without preemption by
        # other processes (the wall-clock figures include it; see load_average).
        "frame_cpu_p50_ms": round(float(np.percentile(cpu_ms, 50)), 3),
        "frame_cpu_p99_ms": round(float(np.percentile(cpu_ms, 99)), 3),
        "frame_p50_ms": round(float(np.percentile(ms, 50)), 3),
        "frame_p99_ms": round(float(np.percentile(ms, 99)), 3),
        "sustained_hz": round(len(times) / total, 1),
        "frames_measured": len(times),
        "model_version": manager.running_version,
    }


def mediapipe_fps() -> float | None:
    try:
        from robot_agent.sources.mediapipe_video import mediapipe_video
    except ImportError:
        return None
    video = str(default_dir() / "video" / "fall-01-cam0.mp4")
    frames = mediapipe_video(video, crop="right", confidence=0.3, keep_rgb=False)
    next(frames)  # model loading and the first frame are not the steady rate
    start = time.perf_counter()
    count = sum(1 for _ in frames)
    return round(count / (time.perf_counter() - start), 1)


def outbox_replay(work: Path) -> float:
    from backend.process import BackendProcess

    env = {
        "VIGIL_DATABASE_URL": f"sqlite:///{work / 'replay.db'}",
        "VIGIL_SECRET_KEY": "bench-robot-secret",
        "VIGIL_FRONTEND_DIR": str(work / "no-frontend"),
    }
    tokens = work / "tokens.json"
    full_env = {**os.environ, **env}
    subprocess.run([sys.executable, "-m", "backend.cli", "migrate"], cwd=ROOT, env=full_env,
                   check=True, capture_output=True)  # fmt: skip
    subprocess.run([sys.executable, "-m", "backend.cli", "seed-demo", "--robots", "1",
                    "--tokens-file", str(tokens), "--no-urfd"], cwd=ROOT, env=full_env,
                   check=True, capture_output=True)  # fmt: skip
    robot_id, token = next(iter(json.loads(tokens.read_text()).items()))
    outbox = Outbox(work / "replay.sqlite", max_frames=1_000_000)
    pipeline = FramePipeline(outbox, None, use_ground_truth=True)
    pipeline.start_transport()
    transport = generate_transport("walking", seed=9, duration_s=REPLAY_FRAMES / 30 + 1)
    truth = transport.decisions()
    for t in range(REPLAY_FRAMES):
        pipeline.process(Observation(t / 30, transport.detections(t), truth=truth[t]))
    queued = len(outbox)
    with BackendProcess(env, log_path=work / "backend.log") as backend:
        client = RobotClient(backend.ws + "/ws/robot", robot_id, token, outbox,
                             backoff=Backoff(base_s=0.05, cap_s=0.2))  # fmt: skip

        async def drain() -> float:
            stop = asyncio.Event()
            start = time.perf_counter()
            task = asyncio.create_task(client.run(stop))
            while len(outbox):
                await asyncio.sleep(0.01)
            elapsed = time.perf_counter() - start
            stop.set()
            await task
            return elapsed

        elapsed = asyncio.run(drain())
    outbox.close()
    return round(queued / elapsed, 1)


def main() -> int:
    model_dir = ensure_model()
    load_before = round(os.getloadavg()[0], 2)
    with tempfile.TemporaryDirectory(prefix="vigil-bench-robot-") as tmp:
        work = Path(tmp)
        result = frame_times(model_dir, work)
        result["mediapipe_fps"] = mediapipe_fps()
        result["outbox_replay_frames_per_s"] = outbox_replay(work)
    result.update(
        goals={"frame_p99_ms_max": 5.0, "mediapipe_fps_min": 15.0},
        replay_frames=REPLAY_FRAMES,
        load_average_1m_at_start=load_before,
        keypoints="GENERATED (vigil.synthetic); depth image: real URFD fall-01 PNG",
        machine={
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "load_average_1m_at_end": round(os.getloadavg()[0], 2),
        },
        measured_at=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
