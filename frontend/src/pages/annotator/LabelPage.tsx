import { useCallback, useEffect, useMemo, useRef, useState } from "react";
import { Link, useParams, useSearchParams } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import { useAuth } from "../../auth/AuthContext";
import { Player } from "./Player";
import { ShortcutsHelp } from "./ShortcutsHelp";
import { Timeline, type TimelineRow } from "./Timeline";
import {
  QUICK_LABELS,
  UndoStack,
  clampFrame,
  labelColours,
  moveActive,
  nextSpeed,
  playbackAdvance,
  searchChoice,
  searchLabels,
  segmentAt,
  spanFromMarks,
  step,
  type Edit,
  type SegmentData,
  type Span,
} from "./timelineLogic";
import type { LabellingVideo, Probability, Segment, SkeletonFrame, TaxonomyLabel } from "./types";
import { classColour } from "./types";

const FRAMES_PER_REQUEST = 2000;
const EDITABLE = new Set(["draft", "pending", "rejected"]);

function dataOf(s: Segment | SegmentData): SegmentData {
  return { first_frame: s.first_frame, last_frame: s.last_frame, label_key: s.label_key };
}

export function LabelPage() {
  const videoId = Number(useParams().videoId);
  const [search] = useSearchParams();
  const { user } = useAuth();
  const [video, setVideo] = useState<LabellingVideo | null>(null);
  const [frames, setFrames] = useState<(SkeletonFrame | undefined)[]>([]);
  const [labels, setLabels] = useState<TaxonomyLabel[]>([]);
  const [segments, setSegments] = useState<Segment[]>([]);
  const [lane, setLane] = useState<Probability | null>(null);
  const [frame, setFrame] = useState(Number(search.get("frame") ?? 0));
  const [playing, setPlaying] = useState(false);
  const [speed, setSpeed] = useState(1);
  const [inPoint, setInPoint] = useState<number | null>(null);
  const [outPoint, setOutPoint] = useState<number | null>(null);
  const [selectedId, setSelectedId] = useState<number | null>(null);
  const [query, setQuery] = useState("");
  const [activeMatch, setActiveMatch] = useState<number | null>(null);
  const [help, setHelp] = useState(false);
  const [showRgb, setShowRgb] = useState(true);
  const [blur, setBlur] = useState(true);
  const [message, setMessage] = useState<string>("");
  const [error, setError] = useState<string | null>(null);
  const undo = useRef(new UndoStack());
  const searchBox = useRef<HTMLInputElement>(null);
  const frameCount = video?.frame_count ?? 0;
  const frameRef = useRef(frame); // read by the key handler, never stale between renders
  frameRef.current = frame;
  const mayUnblur = user?.role === "annotator";

  const loadSegments = useCallback(async () => {
    const { data, error } = await api.GET("/api/labelling/videos/{video_id}/segments", {
      params: { path: { video_id: videoId } },
    });
    if (data) setSegments(data);
    else setError(errorMessage(error, "Could not load segments"));
  }, [videoId]);

  useEffect(() => {
    void (async () => {
      const { data, error } = await api.GET("/api/labelling/videos/{video_id}", {
        params: { path: { video_id: videoId } },
      });
      if (!data) return setError(errorMessage(error, "Could not load the video"));
      setVideo(data);
      const loaded: (SkeletonFrame | undefined)[] = new Array(data.frame_count);
      for (let start = 0; start < data.frame_count; start += FRAMES_PER_REQUEST) {
        const chunk = await api.GET("/api/videos/{video_id}/frames", {
          params: {
            path: { video_id: videoId },
            query: { start, end: Math.min(start + FRAMES_PER_REQUEST, data.frame_count) - 1 },
          },
        });
        for (const f of chunk.data ?? []) loaded[f.index] = f;
      }
      setFrames(loaded);
    })();
    void api.GET("/api/taxonomy").then(({ data }) => data && setLabels(data.labels));
    void api
      .GET("/api/labelling/videos/{video_id}/probability", { params: { path: { video_id: videoId } } })
      .then(({ data }) => data && setLane(data));
    void loadSegments();
  }, [videoId, loadSegments]);

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

  const mine = useCallback(
    (s: Segment) => s.annotator === user?.username || (s.annotator === null && s.source !== "import"),
    [user],
  );

  /** Apply an edit on the server; returns the created id for creates. */
  const apply = useCallback(
    async (edit: Edit): Promise<number | null> => {
      if (edit.kind === "create") {
        const { data, error } = await api.POST("/api/labelling/videos/{video_id}/segments", {
          params: { path: { video_id: videoId } },
          body: { ...edit.data, source: "annotator" },
        });
        if (!data) throw new Error(errorMessage(error, "Could not create the segment"));
        return data.id;
      }
      if (edit.kind === "update") {
        const { error } = await api.PATCH("/api/labelling/segments/{segment_id}", {
          params: { path: { segment_id: edit.id } },
          body: edit.after,
        });
        if (error) throw new Error(errorMessage(error, "Could not change the segment"));
        return null;
      }
      const { error } = await api.DELETE("/api/labelling/segments/{segment_id}", {
        params: { path: { segment_id: edit.id } },
      });
      if (error) throw new Error(errorMessage(error, "Could not delete the segment"));
      return null;
    },
    [videoId],
  );

  const perform = useCallback(
    async (edit: Edit, note: string) => {
      try {
        const id = await apply(edit);
        undo.current.push(id !== null ? { ...edit, id } : edit);
        if (id !== null) setSelectedId(id);
        setError(null);
        setMessage(note);
      } catch (e) {
        setError((e as Error).message);
      }
      await loadSegments();
    },
    [apply, loadSegments],
  );

  const undoRedo = useCallback(
    async (isUndo: boolean) => {
      const edit = isUndo ? undo.current.undo() : undo.current.redo();
      if (!edit) return setMessage(isUndo ? "Nothing to undo" : "Nothing to redo");
      try {
        const id = await apply(edit);
        if (id !== null) undo.current.remap(edit.id, id);
        setError(null);
        setMessage(`${isUndo ? "Undone" : "Redone"}: ${edit.kind} ${edit.kind === "update" ? edit.after.label_key : edit.data.label_key}`);
      } catch (e) {
        undo.current.rollback(isUndo);
        setError((e as Error).message);
      }
      await loadSegments();
    },
    [apply, loadSegments],
  );

  const colours = useMemo(() => labelColours(labels.map((l) => l.key)), [labels]);
  const labelColour = useCallback((key: string) => colours.get(key) ?? "#64748b", [colours]);

  const labelName = useCallback(
    (key: string) => labels.find((l) => l.key === key)?.name ?? key,
    [labels],
  );

  const applyLabel = useCallback(
    async (key: string) => {
      const span = spanFromMarks(inPoint, outPoint);
      if (span) {
        setInPoint(null);
        setOutPoint(null);
        return perform({ kind: "create", id: -1, data: { ...span, label_key: key } },
          `${labelName(key)}: frames ${span.first_frame}–${span.last_frame}`);
      }
      const editable = segments.filter((s) => mine(s) && EDITABLE.has(s.status));
      const target = editable.find((s) => s.id === selectedId) ?? segmentAt(editable, frame);
      if (!target) return setMessage("Set in (I) and out (O) points first, or select one of your segments");
      return perform(
        { kind: "update", id: target.id, before: dataOf(target), after: { ...dataOf(target), label_key: key } },
        `Relabelled as ${labelName(key)}`,
      );
    },
    [inPoint, outPoint, segments, selectedId, frame, mine, perform, labelName],
  );

  const deleteSelected = useCallback(async () => {
    const target = segments.find((s) => s.id === selectedId);
    if (!target || !mine(target) || !EDITABLE.has(target.status))
      return setMessage("Select one of your draft segments to delete");
    setSelectedId(null);
    await perform({ kind: "delete", id: target.id, data: dataOf(target) }, "Segment deleted");
  }, [segments, selectedId, mine, perform]);

  const submit = useCallback(async () => {
    const { data, error } = await api.POST("/api/labelling/videos/{video_id}/submit", {
      params: { path: { video_id: videoId } },
    });
    if (data) {
      setMessage(`Submitted ${data.submitted.length} segment(s) for review`);
      undo.current = new UndoStack(); // submitted segments are the reviewers' now
      setError(null);
    } else setError(errorMessage(error, "Could not submit"));
    await loadSegments();
  }, [videoId, loadSegments]);

  const open3d = useCallback(async () => {
    const { data, error } = await api.POST("/api/labelling/videos/{video_id}/view3d", {
      params: { path: { video_id: videoId }, query: { frame: frameRef.current } },
    });
    if (!data) return setError(errorMessage(error, "Could not open the 3D view"));
    setMessage(`3D view: frame ${data.centre_frame} (nearest with depth) and ${data.frames_shown.length - 1} more`);
    window.open(data.url, "vigil-3d");
  }, [videoId]);

  const quick = useMemo(() => {
    const keys = QUICK_LABELS[video?.mode ?? "walking"] ?? QUICK_LABELS.walking;
    return keys.map((k) => labels.find((l) => l.key === k)).filter((l): l is TaxonomyLabel => !!l);
  }, [labels, video]);

  useEffect(() => {
    const onKey = (event: KeyboardEvent) => {
      const typing = event.target instanceof HTMLInputElement || event.target instanceof HTMLTextAreaElement
        || event.target instanceof HTMLSelectElement;
      if (typing) return;
      const ctrl = event.ctrlKey || event.metaKey;
      const key = event.key;
      let handled = true;
      if (ctrl && key.toLowerCase() === "z") void undoRedo(!event.shiftKey);
      else if (ctrl && key.toLowerCase() === "y") void undoRedo(false);
      else if (ctrl && key === "Enter") void submit();
      else if (ctrl) handled = false;
      else if (key === " ") setPlaying((p) => !p);
      else if (key === "ArrowRight") setFrame((f) => step(f, event.shiftKey ? 10 : 1, frameCount));
      else if (key === "ArrowLeft") setFrame((f) => step(f, event.shiftKey ? -10 : -1, frameCount));
      else if (key === "Home") setFrame(0);
      else if (key === "End") setFrame(Math.max(frameCount - 1, 0));
      else if (key === "i" || key === "I") setInPoint(frameRef.current);
      else if (key === "o" || key === "O") setOutPoint(frameRef.current);
      else if (/^[1-9]$/.test(key) && quick[Number(key) - 1]) void applyLabel(quick[Number(key) - 1].key);
      else if (key === "/") searchBox.current?.focus();
      else if (key === "?") setHelp((h) => !h);
      else if (key === "Escape") { setInPoint(null); setOutPoint(null); setHelp(false); }
      else if (key === "Delete" || key === "Backspace") void deleteSelected();
      else if (key === "[") setSpeed((s) => nextSpeed(s, -1));
      else if (key === "]") setSpeed((s) => nextSpeed(s, 1));
      else if (key === "v" || key === "V") setShowRgb((s) => !s);
      else if ((key === "b" || key === "B") && mayUnblur) setBlur((b) => !b);
      else handled = false;
      if (handled) event.preventDefault();
    };
    window.addEventListener("keydown", onKey);
    return () => window.removeEventListener("keydown", onKey);
  }, [frameCount, quick, applyLabel, undoRedo, submit, deleteSelected, mayUnblur]);

  const rows: TimelineRow[] = useMemo(() => {
    const you = segments.filter(mine);
    const others = new Map<string, Segment[]>();
    for (const s of segments) {
      if (mine(s)) continue;
      const title = s.annotator ?? (s.source === "import" ? "imported" : s.source.replace("_", " "));
      others.set(title, [...(others.get(title) ?? []), s]);
    }
    const list: Omit<TimelineRow, "isEditable">[] = [
      { title: `you (${user?.username ?? ""})`, segments: you, editable: true },
      ...[...others].map(([title, group]) => ({ title, segments: group, editable: user?.role === "admin" })),
    ];
    return list.map((row) => ({
      ...row,
      isEditable: (s: Segment) => row.editable && EDITABLE.has(s.status),
    }));
  }, [segments, mine, user]);

  const onResize = useCallback(
    (id: number, span: Span) => {
      const s = segments.find((x) => x.id === id);
      if (!s || (s.first_frame === span.first_frame && s.last_frame === span.last_frame)) return;
      void perform({ kind: "update", id, before: dataOf(s), after: { ...dataOf(s), ...span } },
        `Moved to frames ${span.first_frame}–${span.last_frame}`);
    },
    [segments, perform],
  );

  const acceptSuggestion = useCallback(
    (span: Span) =>
      void perform({ kind: "create", id: -1, data: { ...span, label_key: "falling" } },
        `Model suggestion accepted as Falling ${span.first_frame}–${span.last_frame}: fix the stages`),
    [perform],
  );

  if (error && !video) return <main className="page"><p role="alert" className="error">{error}</p></main>;
  if (!video) return <main className="page"><p className="muted">Loading…</p></main>;

  const selected = segments.find((s) => s.id === selectedId) ?? null;
  const matches = searchLabels(labels, query).slice(0, 8);
  const timeMs = ((frames[frame]?.ts ?? frame / video.fps) * 1000).toFixed(0);
  const drafts = segments.filter((s) => mine(s) && (s.status === "draft" || s.status === "rejected")).length;
  const laneNote =
    lane?.source === "model" ? `computed · ${lane.model_version}`
      : lane?.source === "stored" ? `stored · ${lane.model_version ?? ""}`
        : lane?.error ? "model failed (see hover)" : "no model scores";

  return (
    <main className="page label-page">
      <div className="label-head">
        <Link to="/annotate">← Videos</Link>
        <h1>{video.name}</h1>
        <span className="muted">
          {video.mode} · split {video.split} · {video.source}
          {video.generated ? " · GENERATED data" : ""} · {video.person ?? "person unknown"}
        </span>
        <span className="exports">
          export accepted:{" "}
          {(["csv", "json", "coco"] as const).map((f) => (
            <a key={f} href={`/api/labelling/videos/${video.id}/export?format=${f}`} download>{f.toUpperCase()}</a>
          ))}
        </span>
        <button type="button" onClick={() => void open3d()} title="Open the frame in 3D (viser)" disabled={!video.has_depth}>
          3D view
        </button>
        <button type="button" onClick={() => setHelp(true)} title="Keyboard shortcuts (?)">?</button>
      </div>
      <div className="label-main">
        <Player video={video} frames={frames} frame={frame} showRgb={showRgb} blur={blur || !mayUnblur} />
        <aside className="label-side">
          <div className="frame-counter" data-testid="frame-counter">
            frame <strong>{frame}</strong> / {frameCount - 1} · {timeMs} ms
          </div>
          <div className="transport">
            <button type="button" onClick={() => setPlaying((p) => !p)}>{playing ? "Pause" : "Play"}</button>
            <span data-testid="speed">{speed}x</span>
            <span>in {inPoint ?? "–"} · out {outPoint ?? "–"}</span>
          </div>
          <label className="toggle">
            <input type="checkbox" checked={showRgb} onChange={() => setShowRgb(!showRgb)} disabled={!video.has_rgb} />
            RGB picture (off = skeleton only)
          </label>
          {mayUnblur && (
            <label className="toggle">
              <input type="checkbox" checked={blur} onChange={() => setBlur(!blur)} /> blur head
            </label>
          )}
          <h2>Labels</h2>
          <ol className="quick-labels">
            {quick.map((l, i) => (
              <li key={l.key}>
                <button type="button" onClick={() => void applyLabel(l.key)}
                  style={{ borderLeft: `6px solid ${labelColour(l.key)}`, borderRight: `4px solid ${classColour(l[video.mode])}` }}>
                  <kbd>{i + 1}</kbd> {l.name}
                </button>
              </li>
            ))}
          </ol>
          <input
            ref={searchBox}
            type="search"
            placeholder="Search labels ( / )"
            aria-label="Search labels"
            aria-controls="label-matches"
            value={query}
            onChange={(e) => {
              setQuery(e.target.value);
              setActiveMatch(null);
            }}
            onKeyDown={(e) => {
              if (e.key === "ArrowDown" || e.key === "ArrowUp") {
                e.preventDefault();
                setActiveMatch((a) => moveActive(a, e.key === "ArrowDown" ? 1 : -1, matches.length));
              } else if (e.key === "Enter") {
                const choice = searchChoice(matches, activeMatch);
                if (!choice) {
                  setMessage(
                    matches.length === 0
                      ? `No label matches “${query}”`
                      : `${matches.length} labels match “${query}”: choose one with ↓ ↑ and Enter, or click it`,
                  );
                  return;
                }
                void applyLabel(choice.key);
                setQuery("");
                setActiveMatch(null);
                e.currentTarget.blur();
              } else if (e.key === "Escape") e.currentTarget.blur();
            }}
          />
          {query && (
            <ul className="label-matches" id="label-matches" data-testid="label-matches">
              {matches.map((l, i) => (
                <li key={l.key}>
                  <button
                    type="button"
                    className={i === activeMatch ? "active" : undefined}
                    aria-current={i === activeMatch ? "true" : undefined}
                    style={{ borderLeft: `6px solid ${labelColour(l.key)}` }}
                    onClick={() => { void applyLabel(l.key); setQuery(""); setActiveMatch(null); }}
                  >
                    {l.name} <span className="muted">{l[video.mode]}</span>
                  </button>
                </li>
              ))}
            </ul>
          )}
          {selected && (
            <p className="selected" data-testid="selected">
              Selected: {selected.label_name ?? selected.label_key} {selected.first_frame}–{selected.last_frame} ({selected.status})
              {selected.review_comment ? ` · “${selected.review_comment}”` : ""}
            </p>
          )}
          <button type="button" className="primary" onClick={() => void submit()} disabled={drafts === 0}>
            Submit {drafts} draft(s) for review
          </button>
          <p className="status-line" role="status" data-testid="status">{message}</p>
          {error && <p role="alert" className="error">{error}</p>}
        </aside>
      </div>
      <Timeline
        frameCount={frameCount}
        fps={video.fps}
        frame={frame}
        rows={rows}
        selectedId={selectedId}
        inPoint={inPoint}
        outPoint={outPoint}
        probability={lane?.source !== "none" ? (lane?.probability ?? null) : null}
        threshold={lane?.threshold ?? null}
        suggestions={lane?.suggestions ?? []}
        laneNote={laneNote}
        laneError={lane?.error ?? null}
        onSeek={(f) => setFrame(clampFrame(f, frameCount))}
        onSelect={setSelectedId}
        onResize={onResize}
        onAcceptSuggestion={acceptSuggestion}
        labelColour={labelColour}
      />
      {help && <ShortcutsHelp onClose={() => setHelp(false)} />}
    </main>
  );
}
