import { useCallback, useMemo } from "react";
import { Link, useParams, useSearchParams } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import { useAuth } from "../../auth/AuthContext";
import { useLabellingData } from "./hooks/useLabellingData";
import { useLabelSearch } from "./hooks/useLabelSearch";
import { useLabelShortcuts } from "./hooks/useLabelShortcuts";
import { useSegments } from "./hooks/useSegments";
import { useStatusLine } from "./hooks/useStatusLine";
import { useTimeline } from "./hooks/useTimeline";
import { useViewOptions } from "./hooks/useViewOptions";
import { Player } from "./Player";
import { ShortcutsHelp } from "./ShortcutsHelp";
import { Timeline } from "./Timeline";
import { QUICK_LABELS, labelColours } from "./timelineLogic";
import type { TaxonomyLabel } from "./types";
import { classColour } from "./types";
import { CLASS_COLOURS, LEGEND } from "../../lib/labelColours";

/** The annotator's workspace for one video: player, quick labels and search, the timeline of
 * everyone's segments. State lives in the hooks under ./hooks; this page composes them. */
export function LabelPage() {
  const videoId = Number(useParams().videoId);
  const [search] = useSearchParams();
  const { user } = useAuth();
  const mayUnblur = user?.role === "annotator";
  const status = useStatusLine();
  const { say, fail } = status;
  const { video, frames, labels, segments, lane, loadSegments } = useLabellingData(videoId, fail);
  const timeline = useTimeline(video, Number(search.get("frame") ?? 0));
  const view = useViewOptions(mayUnblur);

  const colours = useMemo(
    () => labelColours(labels.map((l) => ({ key: l.key, decision: video ? l[video.mode] : null }))),
    [labels, video],
  );
  const labelColour = useCallback((key: string) => colours.get(key) ?? "#64748b", [colours]);
  const labelName = useCallback(
    (key: string) => labels.find((l) => l.key === key)?.name ?? key,
    [labels],
  );
  const quick = useMemo(() => {
    const keys = QUICK_LABELS[video?.mode ?? "walking"] ?? QUICK_LABELS.walking;
    return keys.map((k) => labels.find((l) => l.key === k)).filter((l): l is TaxonomyLabel => !!l);
  }, [labels, video]);

  const edits = useSegments({ videoId, user, segments, loadSegments, labelName, timeline, status });
  const labelSearch = useLabelSearch(labels, edits.applyLabel, say);

  const { frameRef } = timeline;
  const open3d = useCallback(async () => {
    const { data, error } = await api.POST("/api/labelling/videos/{video_id}/view3d", {
      params: { path: { video_id: videoId }, query: { frame: frameRef.current } },
    });
    if (!data) return fail(errorMessage(error, "Could not open the 3D view"));
    say(`3D view: frame ${data.centre_frame} (nearest with depth) and ${data.frames_shown.length - 1} more`);
    window.open(data.url, "vigil-3d");
  }, [videoId, frameRef, say, fail]);

  const { setHelp } = view;
  const closeHelp = useCallback(() => setHelp(false), [setHelp]);
  useLabelShortcuts({
    timeline, quick, applyLabel: edits.applyLabel, undoRedo: edits.undoRedo, submit: edits.submit,
    deleteSelected: edits.deleteSelected, focusSearch: labelSearch.focus, toggleHelp: view.toggleHelp,
    closeHelp, toggleRgb: view.toggleRgb, toggleBlur: view.toggleBlur, mayUnblur,
  });

  const { error, message } = status;
  const { frame, frameCount, playing, speed, inPoint, outPoint } = timeline;
  const { query, matches, activeMatch } = labelSearch;
  const { selected, selectedId, drafts } = edits;

  if (error && !video) return <main className="page"><p role="alert" className="error">{error}</p></main>;
  if (!video) return <main className="page"><p className="muted">Loading…</p></main>;

  const timeMs = ((frames[frame]?.ts ?? frame / video.fps) * 1000).toFixed(0);
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
        <Player video={video} frames={frames} frame={frame} showRgb={view.showRgb} blur={view.blur} />
        <aside className="label-side">
          <div className="frame-counter" data-testid="frame-counter">
            frame <strong>{frame}</strong> / {frameCount - 1} · {timeMs} ms
          </div>
          <div className="transport">
            <button type="button" onClick={timeline.togglePlay}>{playing ? "Pause" : "Play"}</button>
            <span data-testid="speed">{speed}x</span>
            <span>in {inPoint ?? "–"} · out {outPoint ?? "–"}</span>
          </div>
          <label className="toggle">
            <input type="checkbox" checked={view.showRgb} onChange={view.toggleRgb} disabled={!video.has_rgb} />
            RGB picture (off = skeleton only)
          </label>
          {mayUnblur && (
            <label className="toggle">
              <input type="checkbox" checked={view.blurSetting} onChange={view.toggleBlur} /> blur head
            </label>
          )}
          <h2>Labels</h2>
          <ul className="class-legend" aria-label="Colour legend">
            {LEGEND.map((c) => (
              <li key={c.cls}>
                <span className="swatch" style={{ background: CLASS_COLOURS[c.cls] }} /> {c.name}
              </li>
            ))}
          </ul>
          <ol className="quick-labels">
            {quick.map((l, i) => (
              <li key={l.key}>
                <button type="button" onClick={() => void edits.applyLabel(l.key)}
                  style={{ borderLeft: `6px solid ${labelColour(l.key)}`, borderRight: `4px solid ${classColour(l[video.mode])}` }}>
                  <kbd>{i + 1}</kbd> {l.name}
                </button>
              </li>
            ))}
          </ol>
          <input
            ref={labelSearch.box}
            type="search"
            placeholder="Search labels ( / )"
            aria-label="Search labels"
            aria-controls="label-matches"
            value={query}
            onChange={labelSearch.onChange}
            onKeyDown={labelSearch.onKeyDown}
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
                    onClick={() => labelSearch.choose(l.key)}
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
          <button type="button" className="primary" onClick={() => void edits.submit()} disabled={drafts === 0}>
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
        rows={edits.rows}
        selectedId={selectedId}
        inPoint={inPoint}
        outPoint={outPoint}
        probability={lane?.source !== "none" ? (lane?.probability ?? null) : null}
        threshold={lane?.threshold ?? null}
        suggestions={lane?.suggestions ?? []}
        laneNote={laneNote}
        laneError={lane?.error ?? null}
        onSeek={timeline.seek}
        onSelect={edits.setSelectedId}
        onResize={edits.resize}
        onAcceptSuggestion={edits.acceptSuggestion}
        labelColour={labelColour}
      />
      {view.help && <ShortcutsHelp onClose={closeHelp} />}
    </main>
  );
}
