// API shapes of the labelling workspace, from the generated OpenAPI schema.
import type { components } from "../../api/schema";

type S = components["schemas"];

export type LabellingVideo = S["LabellingVideoOut"];
export type Segment = S["SegmentOut"];
export type QueueItem = S["QueueItemOut"];
export type Agreement = S["AgreementOut"];
export type Probability = S["ProbabilityOut"];
export type SkeletonFrame = S["FrameOut"];
export type Taxonomy = S["TaxonomyOut"];
export type TaxonomyLabel = S["TaxonomyLabelOut"];
export type Decision = TaxonomyLabel["walking"];

export { CLASS_COLOURS, classColour } from "../../lib/labelColours";
