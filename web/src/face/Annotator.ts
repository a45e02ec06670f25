// The assisted annotation tool (the avateering paper's §4): the face template superimposed on a still
// image; the annotator poses it (drag to move, wheel to scale, yaw/pitch/roll) and shapes its features
// (the caricature regions: eyes, nose, mouth, jaw, forehead), optionally starting from the tracker's fit;
// saving projects the 468 template vertices to the image: a landmark file with the mirrored copy for the
// flipped image (x ↦ W − x with the left/right vertex permutation, so index i stays template vertex i).
import type { FaceTemplate } from './FaceTemplate';
import { weightedSimilarity } from './reconstruct';

export interface AnnotationPose {
  scale: number;           // pixels per template cm
  yaw: number;             // degrees
  pitch: number;
  roll: number;
  x: number;               // image pixels of the template origin
  y: number;
  weights: number[];       // feature (morph) weights
}

const RAD = Math.PI / 180;

/** R = Rz(roll) · Rx(pitch) · Ry(yaw), row-major (the same convention as the Python tests). */
export function rotation(yaw: number, pitch: number, roll: number): number[] {
  const [a, b, c] = [yaw * RAD, pitch * RAD, roll * RAD];
  const ry = [Math.cos(a), 0, Math.sin(a), 0, 1, 0, -Math.sin(a), 0, Math.cos(a)];
  const rx = [1, 0, 0, 0, Math.cos(b), -Math.sin(b), 0, Math.sin(b), Math.cos(b)];
  const rz = [Math.cos(c), -Math.sin(c), 0, Math.sin(c), Math.cos(c), 0, 0, 0, 1];
  const mul = (p: number[], q: number[]) => [0, 1, 2].flatMap((r) => [0, 1, 2].map((k) =>
    p[3 * r] * q[k] + p[3 * r + 1] * q[3 + k] + p[3 * r + 2] * q[6 + k]));
  return mul(rz, mul(rx, ry));
}

/** Euler angles (yaw, pitch, roll) of R = Rz Rx Ry. */
function angles(r: number[]): [number, number, number] {
  const pitch = Math.asin(Math.max(-1, Math.min(1, r[7])));
  const yaw = Math.atan2(-r[6], r[8]);
  const roll = Math.atan2(-r[1], r[4]);
  return [yaw / RAD, pitch / RAD, roll / RAD];
}

/** The 468 image points (x, y pixels) of the posed, shaped template. */
export function project(t: FaceTemplate, p: AnnotationPose): Float64Array {
  const n = t.vertices.length / 3;
  const R = rotation(p.yaw, p.pitch, p.roll);
  const out = new Float64Array(2 * n);
  for (let i = 0; i < n; i++) {
    const v = [0, 1, 2].map((k) => t.vertices[3 * i + k] + t.morphs.reduce((s, m, j) => s + p.weights[j] * m[3 * i + k], 0));
    out[2 * i] = p.x + p.scale * (R[0] * v[0] + R[1] * v[1] + R[2] * v[2]);
    out[2 * i + 1] = p.y - p.scale * (R[3] * v[0] + R[4] * v[1] + R[5] * v[2]);
  }
  return out;
}

/** The pose that fits tracked 3D landmarks (pixels, z · width), as a starting point for the annotator. */
export function poseFromLandmarks(t: FaceTemplate, landmarks: ArrayLike<number>): AnnotationPose {
  const n = t.vertices.length / 3;
  const points = new Float64Array(3 * n);
  for (let i = 0; i < n; i++) {
    points[3 * i] = landmarks[3 * i]; points[3 * i + 1] = -landmarks[3 * i + 1]; points[3 * i + 2] = -landmarks[3 * i + 2];
  }
  const s = weightedSimilarity(t.vertices, points, t.weights);
  const [yaw, pitch, roll] = angles(s.rotation);
  return { scale: s.scale, yaw, pitch, roll, x: s.translation[0], y: -s.translation[1], weights: t.morphNames.map(() => 0) };
}

/** A landmark file (kinetre.face.landmarks format) for an image of width × height. */
export function landmarkFile(t: FaceTemplate, p: AnnotationPose, width: number, height: number, image: string): object {
  const pts = project(t, p);
  const n = pts.length / 2;
  const round = (x: number) => Math.round(x * 1000) / 1000;
  const landmarks = Array.from({ length: n }, (_, i) => [round(pts[2 * i]), round(pts[2 * i + 1])]);
  const mirrored = Array.from({ length: n }, (_, i) => {
    const j = t.mirror[i];
    return [round(width - pts[2 * j]), round(pts[2 * j + 1])];
  });
  return { format: 'kinetre-face-landmarks', version: 1, image, width, height, landmarks, mirrored, annotation: p };
}
