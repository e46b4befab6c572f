import { useCallback, useMemo, useRef, useState } from "react";
import { api, errorMessage } from "../../../api/client";
import type { useAuth } from "../../../auth/AuthContext";
import type { TimelineRow } from "../Timeline";
import { UndoStack, segmentAt, spanFromMarks, type Edit, type SegmentData, type Span } from "../timelineLogic";
import type { Segment } from "../types";
import type { StatusLine } from "./useStatusLine";
import type { TimelineState } from "./useTimeline";

/** The statuses in which the annotator may still change a segment (backend EDITABLE). */
export const EDITABLE = new Set(["draft", "pending", "rejected"]);

function dataOf(s: Segment | SegmentData): SegmentData {
  return { first_frame: s.first_frame, last_frame: s.last_frame, label_key: s.label_key };
}

interface Options {
  videoId: number;
  user: ReturnType<typeof useAuth>["user"];
  segments: Segment[];
  loadSegments: () => Promise<void>;
  labelName: (key: string) => string;
  timeline: TimelineState;
  status: StatusLine;
}

/** The annotator's segments: selection, create / relabel / resize / delete with undo and redo,
 * submitting the drafts, and the timeline's rows (yours first, then everyone else's). */
export function useSegments({ videoId, user, segments, loadSegments, labelName, timeline, status }: Options) {
  const [selectedId, setSelectedId] = useState<number | null>(null);
  const undo = useRef(new UndoStack());
  const { say, done, fail } = status;
  const { frame, inPoint, outPoint, clearMarks } = timeline;

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
        done(note);
      } catch (e) {
        fail((e as Error).message);
      }
      await loadSegments();
    },
    [apply, loadSegments, done, fail],
  );

  const undoRedo = useCallback(
    async (isUndo: boolean) => {
      const edit = isUndo ? undo.current.undo() : undo.current.redo();
      if (!edit) return say(isUndo ? "Nothing to undo" : "Nothing to redo");
      try {
        const id = await apply(edit);
        if (id !== null) undo.current.remap(edit.id, id);
        done(`${isUndo ? "Undone" : "Redone"}: ${edit.kind} ${edit.kind === "update" ? edit.after.label_key : edit.data.label_key}`);
      } catch (e) {
        undo.current.rollback(isUndo);
        fail((e as Error).message);
      }
      await loadSegments();
    },
    [apply, loadSegments, say, done, fail],
  );

  const applyLabel = useCallback(
    async (key: string) => {
      const span = spanFromMarks(inPoint, outPoint);
      if (span) {
        clearMarks();
        return perform({ kind: "create", id: -1, data: { ...span, label_key: key } },
          `${labelName(key)}: frames ${span.first_frame}–${span.last_frame}`);
      }
      const editable = segments.filter((s) => mine(s) && EDITABLE.has(s.status));
      const target = editable.find((s) => s.id === selectedId) ?? segmentAt(editable, frame);
      if (!target) return say("Set in (I) and out (O) points first, or select one of your segments");
      return perform(
        { kind: "update", id: target.id, before: dataOf(target), after: { ...dataOf(target), label_key: key } },
        `Relabelled as ${labelName(key)}`,
      );
    },
    [inPoint, outPoint, clearMarks, segments, selectedId, frame, mine, perform, labelName, say],
  );

  const deleteSelected = useCallback(async () => {
    const target = segments.find((s) => s.id === selectedId);
    if (!target || !mine(target) || !EDITABLE.has(target.status))
      return say("Select one of your draft segments to delete");
    setSelectedId(null);
    await perform({ kind: "delete", id: target.id, data: dataOf(target) }, "Segment deleted");
  }, [segments, selectedId, mine, perform, say]);

  const submit = useCallback(async () => {
    const { data, error } = await api.POST("/api/labelling/videos/{video_id}/submit", {
      params: { path: { video_id: videoId } },
    });
    if (data) {
      undo.current = new UndoStack(); // submitted segments are the reviewers' now
      done(`Submitted ${data.submitted.length} segment(s) for review`);
    } else fail(errorMessage(error, "Could not submit"));
    await loadSegments();
  }, [videoId, loadSegments, done, fail]);

  const resize = useCallback(
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

  const selected = segments.find((s) => s.id === selectedId) ?? null;
  const drafts = segments.filter((s) => mine(s) && (s.status === "draft" || s.status === "rejected")).length;

  return {
    rows, selected, selectedId, setSelectedId, drafts,
    applyLabel, deleteSelected, submit, undoRedo, resize, acceptSuggestion,
  };
}
