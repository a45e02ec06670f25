// Looking for small people in a wide frame, as `kinetre capture` does (src/kinetre/motion/tiles.py, whose
// numbers a Python test compares with these): the pose detector sees a letterboxed square of the image at
// 224 px, so a person a third of a 640×360 frame's height tall shrinks to a few dozen pixels and is missed.
// Squares as tall as the image's short side, neighbours overlapping by at least a third, show each person at
// up to twice that size; a person found in several is kept once (`distinct`).
import type { Landmark } from './detection';

/** A crop of the image: its top-left corner and size in pixels. */
export interface Tile {
  x: number;
  y: number;
  width: number;
  height: number;
}

/** numpy's round: halves to the even neighbour. */
function roundHalfEven(v: number): number {
  const r = Math.round(v);
  return Math.abs(v % 1) === 0.5 && r % 2 !== 0 ? r - 1 : r;
}

/** The whole image, then (when it is not about square) squares of its short side along its long side,
 * neighbours sharing at least `overlap` of a square, the first and last at the image's ends. */
export function squareTiles(width: number, height: number, overlap = 1 / 3): Tile[] {
  const whole = { x: 0, y: 0, width, height };
  const short = Math.min(width, height), long = Math.max(width, height);
  if (long < 1.2 * short) return [whole];
  const count = Math.ceil((long - short) / ((1 - overlap) * short)) + 1;
  const step = (long - short) / (count - 1);
  const starts = Array.from({ length: count }, (_, i) => roundHalfEven(i === count - 1 ? long - short : i * step));
  return [whole, ...starts.map((s) => (width >= height ? { x: s, y: 0, width: short, height: short }
    : { x: 0, y: s, width: short, height: short }))];
}

/** Landmarks normalised to `tile` → normalised to the whole (width × height) image; z, normalised like x,
 * is rescaled from the tile's width to the image's. */
export function toImage(tile: Tile, marks: Landmark[], width: number, height: number): Landmark[] {
  return marks.map((l) => ({
    ...l, x: (tile.x + l.x * tile.width) / width, y: (tile.y + l.y * tile.height) / height, z: (l.z * tile.width) / width,
  }));
}

function diagonal(p: [number, number][]): number {
  const xs = p.map((q) => q[0]), ys = p.map((q) => q[1]);
  return Math.hypot(Math.max(...xs) - Math.min(...xs), Math.max(...ys) - Math.min(...ys));
}

function median(a: number[]): number {
  const s = [...a].sort((x, y) => x - y), m = s.length >> 1;
  return s.length % 2 ? s[m] : (s[m - 1] + s[m]) / 2;
}

/** Are two detections (corresponding [x, y] landmarks, pixels) the same thing? When the median distance
 * between their landmarks is below `same` times the larger one's size (its landmark box diagonal): the
 * median ignores the few landmarks a square's edge cut off, and people standing close together still
 * differ in most. */
export function repeats(a: [number, number][], b: [number, number][], same = 0.25): boolean {
  return median(a.map((q, n) => Math.hypot(q[0] - b[n][0], q[1] - b[n][1]))) < same * Math.max(diagonal(a), diagonal(b));
}

/** Indices of the detections to keep, best score first (ties in the given order), dropping any that
 * `repeats` a kept one. points: per detection, [x, y] landmarks in pixels. */
export function distinct(points: [number, number][][], scores: number[], same = 0.25): number[] {
  const order = scores.map((_, i) => i).sort((i, j) => scores[j] - scores[i] || i - j);
  const kept: number[] = [];
  for (const i of order) if (!kept.some((k) => repeats(points[i], points[k], same))) kept.push(i);
  return kept;
}

/** Image landmarks (normalised) in pixels, for `distinct`. */
export function pixels(marks: Landmark[], width: number, height: number): [number, number][] {
  return marks.map((l) => [l.x * width, l.y * height]);
}
