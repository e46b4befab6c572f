"""The frame path without a network: observations -> patient -> depth -> model -> outbox."""

from __future__ import annotations

import json
from collections.abc import Iterator

import numpy as np
import pytest

from robot_agent.outbox import Outbox
from robot_agent.pipeline import GROUND_TRUTH_VERSION, Pipeline
from robot_agent.sources.simulator import SimulatorSource
from vigil.classes import TransportMode
from vigil.floor import CameraMount
from vigil.observation import Observation
from vigil.protocol import (
    FrameBatch,
    FrameRecord,
    frame_batch_json,
    frame_body_json,
    frame_json,
    parse_robot_message,
)
from vigil.runtime import FrameClassifier
from vigil.skeleton import N_KEYPOINTS, SkeletonFrame

from .tiny_model import write_upright_model


class FallSource:
    """In-test source: one GENERATED walking patient who falls (vigil.synthetic)."""

    name, fps = "fall", 30.0

    def __iter__(self) -> Iterator[Observation]:
        source = SimulatorSource(
            "walking", seed=3, duration_s=12, n_people=1, events=["fall"], speed=0
        )
        return iter(source)


@pytest.fixture
def model_dir(tmp_path):
    return write_upright_model(tmp_path / "m1", "upright-1", threshold=0.5, delay_ms=200)


def frames_of(outbox: Outbox) -> list[dict]:
    """The queued frames as the backend reads them (strictly, as FrameRecords), every field."""
    return [
        FrameRecord.model_validate_json(m.text, strict=True).model_dump(mode="json")
        for m in outbox.pending(limit=100_000)
        if m.seq is not None
    ]


def test_every_frame_carries_the_models_decision_version_threshold_and_delay(tmp_path, model_dir):
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING, FrameClassifier.from_dir(model_dir))
    pipeline.start_transport("t-1", ts=1_700_000_000.0, patient="GEN-1")
    observations = list(FallSource())
    for observation in observations:
        pipeline.process(observation)
    pipeline.end_transport(1_700_000_100.0)

    messages = outbox.pending(limit=100_000)
    assert json.loads(messages[0].text)["type"] == "transport_start"
    assert json.loads(messages[-1].text)["type"] == "transport_end"
    frames = frames_of(outbox)
    assert [f["seq"] for f in frames] == list(range(len(observations)))
    for frame in frames:
        FrameRecord.model_validate(frame)  # what the backend will accept
        assert (frame["model_version"], frame["threshold"], frame["delay_ms"]) == (
            "upright-1",
            0.5,
            200,
        )
        assert frame["transport_id"] == "t-1"
    decisions = [f["decision"] for f in frames]
    truths = [o.truth for o in observations]
    first_emergency = decisions.index("emergency")
    assert truths[first_emergency] in ("falling", "impact", "lying_on_floor")
    assert decisions[:first_emergency].count("emergency") == 0
    # Wall-clock timestamps: the transport start plus the source's own timing.
    assert frames[0]["ts"] == pytest.approx(1_700_000_000.0)
    assert frames[30]["ts"] - frames[0]["ts"] == pytest.approx(1.0, abs=1e-3)
    assert outbox.oldest_unacked_emergency() is not None


def test_without_a_model_generated_frames_carry_the_ground_truth_marked_as_such(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING, ground_truth_fallback=True)
    assert pipeline.running_model == GROUND_TRUTH_VERSION
    pipeline.start_transport("t-1", ts=0.0)
    for observation in FallSource():
        pipeline.process(observation)
    frames = frames_of(outbox)
    assert {f["model_version"] for f in frames} == {GROUND_TRUTH_VERSION}
    assert all(f["threshold"] is None and f["delay_ms"] is None for f in frames)
    assert "emergency" in {f["decision"] for f in frames}


def test_depth_is_sampled_from_the_depth_image_at_the_patients_keypoints(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING)
    keypoints = np.zeros((N_KEYPOINTS, 3), np.float32)
    keypoints[:, 0], keypoints[:, 1], keypoints[:, 2] = 100 + np.arange(N_KEYPOINTS), 50, 0.9
    keypoints[5, 2] = 0  # missing keypoint: no depth
    depth_image = np.full((120, 160), 2500, np.uint16)  # 2.5 m everywhere
    person = SkeletonFrame(keypoints, timestamp=0.0)
    pipeline.process(Observation(0.0, [person], depth_image=depth_image, depth_scale_mm=1.0))
    (frame,) = frames_of(outbox)
    assert frame["depth"][0] == pytest.approx(2.5)
    assert frame["depth"][5] is None
    assert frame["decision"] is None and frame["model_version"] is None and frame["scores"] == {}


def test_with_a_camera_mount_frames_carry_floor_measures_from_the_sampled_depth(tmp_path):
    mount = CameraMount(fx=100, fy=100, cx=80, cy=60, height_m=1.0, pitch_deg=0.0)
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING, camera_mount=mount)
    keypoints = np.zeros((N_KEYPOINTS, 3), np.float32)
    # A level camera 1 m up, everything 2.5 m away: image row v lies (v - 60) * 2.5 / 100 m
    # below the camera.
    keypoints[:, 0], keypoints[:, 1], keypoints[:, 2] = 80, np.linspace(20, 100, N_KEYPOINTS), 1
    depth_image = np.full((120, 160), 2500, np.uint16)
    person = SkeletonFrame(keypoints, timestamp=0.0)
    pipeline.process(Observation(0.0, [person], depth_image=depth_image, depth_scale_mm=1.0))
    pipeline.process(Observation(0.1, [person]))  # no depth image: nothing to measure
    with_depth, without = frames_of(outbox)
    heights = 1.0 - (keypoints[:, 1] - 60) * 2.5 / 100
    assert with_depth["floor"] == pytest.approx(
        [heights.max(), heights.mean(), np.mean(heights < 0.4)], abs=1e-4
    )
    assert without["floor"] is None


def test_floor_measures_a_source_knows_travel_unchanged(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING)
    keypoints = np.zeros((N_KEYPOINTS, 3), np.float32)
    keypoints[:, 0], keypoints[:, 1], keypoints[:, 2] = 50, np.arange(N_KEYPOINTS), 1
    person = SkeletonFrame(keypoints, timestamp=0.0, floor=[0.45, 0.2, np.nan])
    pipeline.process(Observation(0.0, [person]))
    (frame,) = frames_of(outbox)
    assert frame["floor"][:2] == pytest.approx([0.45, 0.2]) and frame["floor"][2] is None


def test_nobody_in_view_still_sends_a_frame_without_keypoints(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING)
    result = pipeline.process(Observation(0.0, []))
    assert not result.seen
    (frame,) = frames_of(outbox)
    assert all(point[2] == 0 for point in frame["keypoints"])


def test_swapped_model_takes_over_between_two_frames_warmed_up(tmp_path, model_dir):
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING, FrameClassifier.from_dir(model_dir))
    pipeline.start_transport("t-1", ts=0.0)
    observations = list(FallSource())
    for observation in observations[:100]:
        pipeline.process(observation)
    v2 = FrameClassifier.from_dir(write_upright_model(tmp_path / "m2", "upright-2", delay_ms=0))
    pipeline.swap_model(v2)
    assert pipeline.running_model == "upright-2"
    for observation in observations[100:]:
        pipeline.process(observation)
    versions = [f["model_version"] for f in frames_of(outbox)]
    assert versions == ["upright-1"] * 100 + ["upright-2"] * (len(observations) - 100)


def test_a_shadow_model_decides_beside_the_model_and_travels_with_the_frame(tmp_path, model_dir):
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING, FrameClassifier.from_dir(model_dir))
    pipeline.start_transport("t-1", ts=0.0)
    observations = list(FallSource())
    for observation in observations[:50]:
        pipeline.process(observation)
    candidate = write_upright_model(tmp_path / "c", "upright-candidate", threshold=0.9)
    pipeline.set_shadow(FrameClassifier.from_dir(candidate))
    for observation in observations[50:]:
        pipeline.process(observation)
    frames = frames_of(outbox)
    assert all(f["shadow"] is None for f in frames[:50])
    shadows = [f["shadow"] for f in frames[50:]]
    assert {s["model_version"] for s in shadows} == {"upright-candidate"}
    assert {f["model_version"] for f in frames} == {"upright-1"}  # the model still decides
    assert "emergency" in {s["decision"] for s in shadows}
    pipeline.set_shadow(None)
    pipeline.process(observations[-1])
    assert frames_of(outbox)[-1]["shadow"] is None


def test_queued_frames_are_the_protocols_frames_and_go_out_as_its_batch(tmp_path, model_dir):
    """The pipeline's frame bodies are vigil.protocol's (frame_body_json, None fields left out),
    with and without a transport, model or shadow; numbered and batched by the protocol's
    builders they are what the backend parses, strictly, into the same FrameRecords."""
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING)
    observations = list(FallSource())
    pipeline.process(observations[0])  # no transport, no model: no decision
    pipeline.swap_model(FrameClassifier.from_dir(model_dir))
    pipeline.start_transport("t-ü-1", ts=1_700_000_000.0)
    for observation in observations[1:40]:
        pipeline.process(observation)
    pipeline.set_shadow(FrameClassifier.from_dir(model_dir))
    for observation in observations[40:80]:
        pipeline.process(observation)
    pending = [m for m in outbox.pending(limit=100_000) if m.seq is not None]
    assert len(pending) == 80
    records = [FrameRecord.model_validate_json(m.text, strict=True) for m in pending]
    for message, record in zip(pending, records, strict=True):
        assert message.text == frame_json(message.seq, frame_body_json(record))
        assert record.seq == message.seq
    bare = json.loads(pending[0].text)  # no transport, no decision: None fields left out
    assert None not in bare.values() and not {"transport_id", "decision", "shadow"} & set(bare)
    assert records[0].transport_id is None and records[0].decision is None
    assert {r.transport_id for r in records[1:]} == {"t-ü-1"}
    assert all(r.shadow is None for r in records[:40])
    assert all(r.shadow is not None for r in records[40:])
    batch = frame_batch_json([m.text for m in pending])
    assert parse_robot_message(batch) == FrameBatch(frames=records)


def _statuses(outbox: Outbox) -> list[dict]:
    messages = [json.loads(m.text) for m in outbox.pending(limit=100_000) if m.seq is None]
    return [m for m in messages if m["type"] == "detection_status"]


def test_losing_floor_measures_switches_to_the_fallback_and_raises_degraded(tmp_path):
    """A floor model whose frames stop carrying floor measures: after DEGRADE_AFTER_S the
    keypoints-only fallback decides (and catches the fall the floor model would not), a
    detection_status message says so once, and floor measures coming back end it."""
    floor_model = FrameClassifier.from_dir(
        write_upright_model(
            tmp_path / "floor", "floor-1", delay_ms=0, feature_set="full", always_normal=True
        )
    )
    fallback = FrameClassifier.from_dir(
        write_upright_model(tmp_path / "kp", "kp-1", delay_ms=0, feature_set="keypoints")
    )
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING, floor_model, fallback=fallback)
    pipeline.start_transport("t-1", ts=1_700_000_000.0)
    decisions = []
    for obs in FallSource():
        # The depth stream stops 2 s in: no floor measures from then on, until 9 s.
        lost = 2.0 <= obs.timestamp < 9.0
        people = [
            SkeletonFrame(
                p.keypoints,
                p.depth,
                p.timestamp,
                np.full(3, np.nan) if lost else np.array([1.7, 0.9, 0.0]),
            )
            for p in obs.people
        ]
        result = pipeline.process(Observation(obs.timestamp, people, obs.index, truth=obs.truth))
        decisions.append((obs.timestamp, result.decision, result.classification.model_version))
    statuses = _statuses(outbox)
    assert [s["degraded"] for s in statuses] == [True, False]
    degraded, recovered = statuses
    assert degraded["missing_inputs"] == ["floor"]
    assert degraded["assigned_model"] == "floor-1" and degraded["running_model"] == "kp-1"
    assert "floor measures" in degraded["reason"] and degraded["transport_id"] == "t-1"
    assert recovered["running_model"] == "floor-1"
    deciding = {version for ts, _, version in decisions if 2.6 <= ts < 9.0}
    assert deciding == {"kp-1"}
    assert {version for ts, _, version in decisions if ts < 2.4 or ts > 10.1} == {"floor-1"}
    assert any(d.value == "emergency" for ts, d, v in decisions if v == "kp-1")
    assert pipeline.running_model == "floor-1"  # the assigned model, what the fleet compares


def test_a_robot_that_cannot_feed_its_model_reports_degraded_at_once_every_transport(tmp_path):
    floor_model = FrameClassifier.from_dir(
        write_upright_model(tmp_path / "floor", "floor-1", feature_set="full")
    )
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING, floor_model, available_inputs=["keypoints"])
    for transport in ("t-1", "t-2"):
        pipeline.start_transport(transport, ts=1_700_000_000.0)
        for i, obs in enumerate(FallSource()):
            result = pipeline.process(obs)
            assert result.decision is not None  # it keeps deciding
            if i == 5:
                break
        pipeline.end_transport(1_700_000_100.0)
    statuses = _statuses(outbox)
    assert [(s["transport_id"], s["degraded"]) for s in statuses] == [("t-1", True), ("t-2", True)]
    assert statuses[0]["running_model"] == "floor-1"
    assert "no keypoints-only fallback" in statuses[0]["reason"]


def test_transport_start_carries_the_source_frame_rate_and_end_logs_counts(tmp_path, caplog):
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING)
    pipeline.start_transport("t-1", ts=1_700_000_000.0, fps=23.976)
    for i in range(25):
        people = [] if i % 5 == 0 else list(next(iter(FallSource())).people)
        pipeline.process(Observation(i / 23.976, people, i))
    with caplog.at_level("INFO", logger="robot_agent.pipeline"):
        pipeline.end_transport(1_700_000_100.0)
    start = json.loads(next(m.text for m in outbox.pending(limit=100) if m.seq is None))
    assert start["type"] == "transport_start" and start["fps"] == 23.976
    (line,) = [r.getMessage() for r in caplog.records if "ended" in r.getMessage()]
    assert (
        "25 frames, 20 with a person in view, 20 with the patient, 0 refused as implausible "
        "(not a person: not dropped), 24.0 frames/s"
    ) in line


def test_transport_end_counts_frames_refused_as_implausible_apart(tmp_path, caplog):
    """The patient walks, goes down and is lost; the pose estimator then reports a whole "person"
    far from where they lay (the office chair): those frames are counted as refused, not as
    frames with the patient, and the detector says they are not dropped."""
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = Pipeline(outbox, TransportMode.WALKING)
    pipeline.start_transport("t-1", ts=1_700_000_000.0, fps=30.0)
    person = next(o for o in FallSource() if o.people).people[0]
    kp = person.keypoints.copy()
    present = kp[:, 2] > 0
    size = float(np.ptp(kp[present, 1]))
    chair_kp = kp.copy()
    chair_kp[present, 0] -= 3 * size
    chair = SkeletonFrame(chair_kp, timestamp=0.0)
    detected = []
    for i in range(40):
        people = [person] if i < 20 else [] if i < 22 else [chair]
        pipeline.process(Observation(i / 30, people, i))
        detected.append(pipeline.detector.patient_frames.refused_)
    with caplog.at_level("INFO", logger="robot_agent.pipeline"):
        pipeline.end_transport(1_700_000_100.0)
    (line,) = [r.getMessage() for r in caplog.records if "ended" in r.getMessage()]
    assert "40 frames, 38 with a person in view, 20 with the patient, 18 refused" in line
    assert detected[22:] == [1] * 18


class _SlowClock:
    """A monotonic clock that advances `step` seconds on every reading (GENERATED timing)."""

    def __init__(self, step: float) -> None:
        self.now, self.step = 100.0, step

    def __call__(self) -> float:
        self.now += self.step
        return self.now


def _transport_end_line(tmp_path, caplog, clock_step: float, cpu_step: float = 0.001) -> str:
    """30 frames of a 30 frames/s source through a pipeline whose clocks advance by the given
    steps on every reading; the transport-end log line."""
    pipeline = Pipeline(
        Outbox(tmp_path / "o.sqlite"),
        TransportMode.WALKING,
        clock=_SlowClock(clock_step),
        cpu_clock=_SlowClock(cpu_step),
    )
    pipeline.start_transport("t-1", ts=1_700_000_000.0, fps=30.0)
    for i in range(30):
        pipeline.process(Observation(i / 30.0, [], i))
    with caplog.at_level("INFO", logger="robot_agent.pipeline"):
        pipeline.end_transport(1_700_000_100.0)
    (line,) = [r.getMessage() for r in caplog.records if "ended" in r.getMessage()]
    return line


def test_transport_end_logs_how_far_the_robot_fell_behind_the_source_pace(tmp_path, caplog):
    """Every reading of the clock advances 25 ms: 50 ms from one frame's end to the next
    against the source's 33.3 ms, so after 30 frames the robot is 29 x 16.7 ms = 0.48 s behind;
    the frame path itself took 25 ms a frame."""
    line = _transport_end_line(tmp_path, caplog, 0.025, 0.040)
    assert "at most 0.48 s behind the source's pace" in line
    assert "frame path 25.0 ms a frame on average (max 25.0 ms)" in line
    assert "40.0 ms of the process's CPU a frame" in line  # more than 33 ms: no core keeps up


def test_a_robot_keeping_up_is_not_behind(tmp_path, caplog):
    line = _transport_end_line(tmp_path, caplog, 0.005)
    assert "at most 0.00 s behind" in line
