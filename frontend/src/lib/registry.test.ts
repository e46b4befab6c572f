import { describe, expect, it } from "vitest";
import { goldSplitText, jobResultLink, listView, metricName, statusText } from "./registry";

describe("model status in true words", () => {
  it("says on how many robots a production model runs", () => {
    expect(statusText({ status: "production", robots_assigned: 1, robots_in_fleet: 3 })).toBe(
      "production on 1 of 3 robots",
    );
    expect(statusText({ status: "production", robots_assigned: 3, robots_in_fleet: 3 })).toBe(
      "production on every robot",
    );
    expect(statusText({ status: "production", robots_assigned: 0, robots_in_fleet: 3 })).toBe(
      "production, on no robot",
    );
  });

  it("names the canary robot and leaves other states alone", () => {
    expect(statusText({ status: "approved", robots_assigned: 1, robots_in_fleet: 3, canary_robot: "robot-1" }))
      .toBe("canary on robot-1");
    expect(statusText({ status: "candidate", robots_assigned: 0, robots_in_fleet: 3 })).toBe("candidate");
  });
});

describe("metric names", () => {
  it("reads fp_d and fn_d in words, and falls back to the key without underscores", () => {
    expect(metricName("fp_d")).toBe("False-positive frames after the delay filter");
    expect(metricName("fn_d")).toBe("False-negative frames after the delay filter");
    expect(metricName("some_new_metric")).toBe("some new metric");
  });
});

describe("search, sort and pages", () => {
  const rows = Array.from({ length: 53 }, (_, i) => ({ name: `rf-${String(i).padStart(2, "0")}`, f1: i % 7 }));
  const view = (query: string, page: number, direction: "asc" | "desc" = "asc") =>
    listView(rows, (r) => r.name, query, (r) => r.name, direction, page, 25);

  it("cuts the list into pages and clamps the page number", () => {
    expect(view("", 0).rows).toHaveLength(25);
    expect(view("", 2).rows.map((r) => r.name)).toEqual(["rf-50", "rf-51", "rf-52"]);
    expect(view("", 9).page).toBe(2);
    expect(view("", 0).pages).toBe(3);
  });

  it("filters by every word of the query and sorts both ways", () => {
    expect(view("rf 4", 0).total).toBe(14); // rf-04, rf-14, ..., rf-40..rf-49
    expect(view("", 0, "desc").rows[0].name).toBe("rf-52");
    expect(view("nothing", 0)).toMatchObject({ total: 0, pages: 1, page: 0 });
  });
});

describe("job result link", () => {
  it("links the new version only for jobs that register one", () => {
    expect(jobResultLink("retrain", { model_version_id: 4, version: "mlp-9" })).toEqual({ modelId: 4, text: "mlp-9" });
    expect(jobResultLink("whatif", { model_version_id: 2 })).toEqual({ modelId: 2, text: "ran on model #2" });
    expect(jobResultLink("evaluate", { model_version_id: 2 })!.text).not.toContain("new version");
    expect(jobResultLink("retention", { summary: "x" })).toBeNull();
  });
});

describe("where the gold-set figures come from", () => {
  it("says the gold recordings were not training data", () => {
    expect(goldSplitText({ gold_recordings: 14, training_recordings: 56, overlap: [] })).toEqual({
      text: "Judged on 14 gold recordings it was not trained on (trained on 56 other recordings).",
      clean: true,
    });
  });

  it("names the gold recordings it was trained on", () => {
    const said = goldSplitText({ gold_recordings: 4, training_recordings: 14, overlap: ["adl-07", "fall-08"] });
    expect(said.clean).toBe(false);
    expect(said.text).toBe(
      "Judged on 4 gold recordings, 2 of which it was trained on (adl-07, fall-08): training figures, so the gate refuses it.",
    );
  });

  it("says when nothing records what it was trained on", () => {
    const said = goldSplitText({ gold_recordings: 1, training_recordings: null, overlap: null });
    expect(said.clean).toBe(false);
    expect(said.text).toContain("Judged on 1 gold recording, but its training recordings are unknown");
  });
});
