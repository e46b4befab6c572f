import { useCallback, useEffect, useState } from "react";
import { api, errorMessage } from "../../../api/client";
import type { LabellingVideo, Probability, Segment, SkeletonFrame, TaxonomyLabel } from "../types";

const FRAMES_PER_REQUEST = 2000;

/** What the label page shows of one video: the video, its skeleton frames, the taxonomy, the
 * segments (reloaded after every change) and the model's probability lane. */
export function useLabellingData(videoId: number, fail: (error: string) => void) {
  const [video, setVideo] = useState<LabellingVideo | null>(null);
  const [frames, setFrames] = useState<(SkeletonFrame | undefined)[]>([]);
  const [labels, setLabels] = useState<TaxonomyLabel[]>([]);
  const [segments, setSegments] = useState<Segment[]>([]);
  const [lane, setLane] = useState<Probability | null>(null);

  const loadSegments = useCallback(async () => {
    const { data, error } = await api.GET("/api/labelling/videos/{video_id}/segments", {
      params: { path: { video_id: videoId } },
    });
    if (data) setSegments(data);
    else fail(errorMessage(error, "Could not load segments"));
  }, [videoId, fail]);

  useEffect(() => {
    void (async () => {
      const { data, error } = await api.GET("/api/labelling/videos/{video_id}", {
        params: { path: { video_id: videoId } },
      });
      if (!data) return fail(errorMessage(error, "Could not load the video"));
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
  }, [videoId, loadSegments, fail]);

  return { video, frames, labels, segments, lane, loadSegments };
}
