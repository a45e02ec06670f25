// Algorithm 2 in the page, the same steps as kinetre/face/reconstruct.py (which documents the math):
// UVs from the landmarks, weighted similarity alignment to the frontal template (Horn's quaternion form
// of the weighted least squares), x, y back-projected with the template's depth, template units, chin at
// the origin. The anchor (an avatar's neck, or the puppet's stand) is the object transform in three.js.
import type { FaceTemplate } from './FaceTemplate';

export interface Similarity {
  scale: number;
  rotation: number[];       // 3 × 3 row-major, template → camera (y up, z towards the camera)
  translation: number[];
}

export interface FaceShape {
  face: Float32Array;       // 468 × 3 metres, the frontal face with its chin at the origin
  uvs: Float32Array;        // 468 × 2, three.js convention (v up): (x / w, 1 − y / h)
  pose: Similarity;
}

const CM = 0.01;

/** Largest-eigenvalue eigenvector of a symmetric 4 × 4 matrix (cyclic Jacobi). */
function topEigenvector(a: number[][]): number[] {
  const n = 4;
  const v = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]];
  for (let sweep = 0; sweep < 30; sweep++) {
    let off = 0;
    for (let p = 0; p < n; p++) for (let q = p + 1; q < n; q++) off += a[p][q] * a[p][q];
    if (off < 1e-20) break;
    for (let p = 0; p < n; p++) {
      for (let q = p + 1; q < n; q++) {
        if (Math.abs(a[p][q]) < 1e-30) continue;
        const theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
        const c = 1 / Math.sqrt(t * t + 1), s = t * c;
        for (let k = 0; k < n; k++) {
          const akp = a[k][p], akq = a[k][q];
          a[k][p] = c * akp - s * akq; a[k][q] = s * akp + c * akq;
        }
        for (let k = 0; k < n; k++) {
          const apk = a[p][k], aqk = a[q][k];
          a[p][k] = c * apk - s * aqk; a[q][k] = s * apk + c * aqk;
        }
        for (let k = 0; k < n; k++) {
          const vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq; v[k][q] = s * vkp + c * vkq;
        }
      }
    }
  }
  let best = 0;
  for (let i = 1; i < n; i++) if (a[i][i] > a[best][best]) best = i;
  return [v[0][best], v[1][best], v[2][best], v[3][best]];
}

/** The similarity minimising Σ w_i ‖b_i − (s R a_i + t)‖² (Horn 1987, weighted); points as flat xyz arrays. */
export function weightedSimilarity(a: Float32Array | number[], b: ArrayLike<number>, w: ArrayLike<number>): Similarity {
  let sw = 0;
  const ma = [0, 0, 0], mb = [0, 0, 0];
  for (let i = 0; i < w.length; i++) {
    if (!(w[i] > 0)) continue;
    sw += w[i];
    for (let k = 0; k < 3; k++) { ma[k] += w[i] * a[3 * i + k]; mb[k] += w[i] * b[3 * i + k]; }
  }
  for (let k = 0; k < 3; k++) { ma[k] /= sw; mb[k] /= sw; }
  const S = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
  let va = 0;
  for (let i = 0; i < w.length; i++) {
    if (!(w[i] > 0)) continue;
    const x = [a[3 * i] - ma[0], a[3 * i + 1] - ma[1], a[3 * i + 2] - ma[2]];
    const y = [b[3 * i] - mb[0], b[3 * i + 1] - mb[1], b[3 * i + 2] - mb[2]];
    for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) S[r][c] += w[i] * x[r] * y[c];
    va += w[i] * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  }
  const [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]] = S;
  const [q0, q1, q2, q3] = topEigenvector([
    [xx + yy + zz, yz - zy, zx - xz, xy - yx],
    [yz - zy, xx - yy - zz, xy + yx, zx + xz],
    [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
    [xy - yx, zx + xz, yz + zy, -xx - yy + zz],
  ]);
  const R = [
    q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2),
    2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1),
    2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3,
  ];
  let num = 0;
  for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) num += R[3 * r + c] * S[c][r];
  const scale = num / va;
  const t = [0, 1, 2].map((r) => mb[r] - scale * (R[3 * r] * ma[0] + R[3 * r + 1] * ma[1] + R[3 * r + 2] * ma[2]));
  return { scale, rotation: R, translation: t };
}

/** Algorithm 2 on 468 landmarks in pixels (x right, y down, z = MediaPipe's depth · width); null when the
 *  head is turned too far to back-project (the caller keeps the last good face). */
export function reconstructFace(t: FaceTemplate, landmarks: ArrayLike<number>, width: number, height: number): FaceShape | null {
  const n = t.vertices.length / 3;
  const uvs = new Float32Array(2 * n);
  const points = new Float64Array(3 * n);
  for (let i = 0; i < n; i++) {
    const x = landmarks[3 * i], y = landmarks[3 * i + 1], z = landmarks[3 * i + 2];
    if (!Number.isFinite(x) || !Number.isFinite(y) || !Number.isFinite(z)) return null;
    uvs[2 * i] = x / width;
    uvs[2 * i + 1] = 1 - y / height;
    points[3 * i] = x; points[3 * i + 1] = -y; points[3 * i + 2] = -z;
  }
  const pose = weightedSimilarity(t.vertices, points, t.weights);
  const R = pose.rotation;
  const det = R[0] * R[4] - R[1] * R[3];
  if (Math.abs(det) < 0.15 || !(pose.scale > 0)) return null;
  const face = new Float32Array(3 * n);
  for (let i = 0; i < n; i++) {
    const z = t.vertices[3 * i + 2];
    const qx = (points[3 * i] - pose.translation[0]) / pose.scale - R[2] * z;
    const qy = (points[3 * i + 1] - pose.translation[1]) / pose.scale - R[5] * z;
    face[3 * i] = (R[4] * qx - R[1] * qy) / det;
    face[3 * i + 1] = (-R[3] * qx + R[0] * qy) / det;
    face[3 * i + 2] = z;
  }
  const c = 3 * t.chin;
  const [cx, cy, cz] = [face[c], face[c + 1], face[c + 2]];
  for (let i = 0; i < n; i++) {
    face[3 * i] = CM * (face[3 * i] - cx);
    face[3 * i + 1] = CM * (face[3 * i + 1] - cy);
    face[3 * i + 2] = CM * (face[3 * i + 2] - cz);
  }
  return { face, uvs, pose };
}
