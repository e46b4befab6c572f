import { useCallback, useEffect, useState } from "react";
import { Link } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import { useAuth } from "../../auth/AuthContext";
import { classColour, type QueueItem } from "./types";

/** Reviewers accept or reject submitted and proposed segments, most informative first. */
export function ReviewPage() {
  const { user } = useAuth();
  const [queue, setQueue] = useState<QueueItem[] | null>(null);
  const [comments, setComments] = useState<Record<number, string>>({});
  const [error, setError] = useState<string | null>(null);

  const load = useCallback(async () => {
    const { data, error } = await api.GET("/api/labelling/review-queue");
    if (data) setQueue(data);
    else setError(errorMessage(error, "Could not load the review queue"));
  }, []);
  useEffect(() => void load(), [load]);

  const review = async (id: number, decision: "accept" | "reject") => {
    const { error } = await api.POST("/api/labelling/segments/{segment_id}/review", {
      params: { path: { segment_id: id } },
      body: { decision, comment: comments[id] || null },
    });
    setError(error ? errorMessage(error, "Review failed") : null);
    await load();
  };

  return (
    <main className="page">
      <div className="label-head">
        <Link to="/annotate">← Videos</Link>
        <h1>Review queue</h1>
      </div>
      <p className="muted">
        Alarms nurses rejected as false come first, then segments where a model disagrees, then
        the rest. Rejecting needs a comment that tells the annotator what to fix.
      </p>
      {error && <p role="alert" className="error">{error}</p>}
      {!queue ? <p className="muted">Loading…</p> : queue.length === 0 ? (
        <p className="empty">Nothing to review.</p>
      ) : (
        <table className="videos" aria-label="Review queue">
          <thead>
            <tr><th>Why</th><th>Video</th><th>Frames</th><th>Label</th><th>By</th><th>Comment</th><th /></tr>
          </thead>
          <tbody>
            {queue.map(({ segment: s, video_name, reason }) => (
              <tr key={s.id} data-testid="queue-row" data-segment-id={s.id}>
                <td>{reason}</td>
                <td>
                  <Link to={`/annotate/videos/${s.video_id}?frame=${s.first_frame}`}>{video_name}</Link>
                </td>
                <td>{s.first_frame}–{s.last_frame}</td>
                <td>
                  <span className="swatch" style={{ background: classColour(s.decision) }} />
                  {s.label_name ?? s.label_key}
                </td>
                <td>{s.annotator ?? s.source.replace("_", " ")}</td>
                <td>
                  <input aria-label={`Comment on segment ${s.id}`} value={comments[s.id] ?? ""}
                    onChange={(e) => setComments({ ...comments, [s.id]: e.target.value })} />
                </td>
                <td className="actions">
                  {s.annotator !== null && s.annotator === user?.username ? (
                    <span className="muted" data-testid="own-segment">your segment: another reviewer decides</span>
                  ) : (
                    <>
                      <button type="button" className="primary" onClick={() => void review(s.id, "accept")}>Accept</button>
                      <button type="button" onClick={() => void review(s.id, "reject")}>Reject</button>
                    </>
                  )}
                </td>
              </tr>
            ))}
          </tbody>
        </table>
      )}
    </main>
  );
}
