// The hands and face of a skeleton message (src/kinetre/studio/protocol.py): "hands" [left, right], each null
// or 21 [x, y, z] in the skeleton's frame (metres, +Y up, the wrist at the body's wrist), and "blendshapes",
// FaceLandmarker's 52 weights in its order (BLENDSHAPES), so the names never travel with every frame.
import { BLENDSHAPES } from '../avatar/Expressions';
import type { Vec3 } from './protocol';

export interface HandsFaceFields {
  hands?: (Vec3[] | null)[];
  blendshapes?: number[];
}

const round = (x: number, step: number): number => Math.round(x / step) * step;

/** The message fields for `hands` ([left, right]) and a face's `scores` by name; a field is left out when
 * nothing of it is seen, or when the face lacks one of the 52 names. Positions go at 0.1 mm, weights at 1e-4. */
export function handsFaceFields(hands: (Vec3[] | null)[] | undefined, scores: Record<string, number> | null | undefined): HandsFaceFields {
  const out: HandsFaceFields = {};
  if (hands && hands.length === 2 && hands.some((h) => h)) {
    out.hands = hands.map((h) => (h ? h.map((p) => p.map((c) => round(c, 1e-4)) as Vec3) : null));
  }
  if (scores && BLENDSHAPES.every((n) => Number.isFinite(scores[n]))) {
    out.blendshapes = BLENDSHAPES.map((n) => round(Math.min(1, Math.max(0, scores[n])), 1e-4));
  }
  return out;
}

/** A message's blendshapes back as scores by name (null without them). */
export function faceScores(blendshapes: number[] | null | undefined): Record<string, number> | null {
  if (!blendshapes || blendshapes.length !== BLENDSHAPES.length) return null;
  return Object.fromEntries(BLENDSHAPES.map((n, i) => [n, blendshapes[i]]));
}
