// Tracked Kinect-20 joints → an avatar's own joint transforms, one frame at a time: the avateering paper's
// Algorithm 1 (avateering paper §3), the same loop as src/kinetre/avatar/retarget.py `_frames` (a Python test runs
// both on one fixture and compares the numbers). The plan (rest directions d_i, the root frame, the facing
// turn, bind matrices) comes from the server, which maps the bones (by VRM, names or geometry).
//
// Per joint, parents first: s = P_c − P_i, q_lo = the minimal rotation taking the parent-carried rest
// direction onto s, world rotation q = q_lo · q_parent, local q_i = q_parent⁻¹ · q; spine and chest turn
// about their bone with the shoulder line; the root turns with the hips and shoulders and travels by the
// hip centre's displacement times the leg-length ratio. Untracked bones keep their last local rotation.
// No dependency on three.js: plain arrays, row-major 3x3 and 4x4 matrices.

export type M3 = number[][];
export type M4 = number[][];
export type V3 = number[];

/** RetargetPlan.to_json() of the Python side. */
export interface RetargetPlan {
  order: number[];
  parents: number[];
  real_parents: number[];
  fixed_parent: M4[];
  root: number;
  aim_from: number[];
  aim_to: number[];
  twist: boolean[];
  rest_aim: V3[];
  rest_shoulders: V3;
  root_frame: M3;
  bind_linear: M3[];
  bind_positions: V3[];
  align: M3;
  leg_length: number;
}

export interface AvatarFrame {
  world: M4[]; // per joint
  local: M4[]; // per joint, relative to its glTF parent node
  rotations: M3[]; // per joint, its world rotation from the bind pose (q of Algorithm 1)
}

const K = { HipCenter: 0, ShoulderCenter: 2, ShoulderLeft: 4, ShoulderRight: 8, HipLeft: 12, KneeLeft: 13,
  AnkleLeft: 14, HipRight: 16, KneeRight: 17, AnkleRight: 18 };

export const eye3 = (): M3 => [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
export const sub = (a: V3, b: V3): V3 => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
export const add = (a: V3, b: V3): V3 => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
export const scale = (a: V3, s: number): V3 => [a[0] * s, a[1] * s, a[2] * s];
export const dot = (a: V3, b: V3): number => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
export const cross = (a: V3, b: V3): V3 => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
export const norm = (a: V3): number => Math.sqrt(dot(a, a));
export const transpose = (a: number[][]): number[][] => a[0].map((_, j) => a.map((row) => row[j]));

export function mm(a: number[][], b: number[][]): number[][] {
  const out = a.map(() => new Array(b[0].length).fill(0));
  for (let i = 0; i < a.length; i++) {
    for (let k = 0; k < b.length; k++) {
      const aik = a[i][k];
      for (let j = 0; j < b[0].length; j++) out[i][j] += aik * b[k][j];
    }
  }
  return out;
}

export function mv(a: number[][], v: V3): V3 {
  return a.map((row) => row[0] * v[0] + row[1] * v[1] + row[2] * v[2]);
}

function skew(a: V3): M3 {
  return [[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]];
}

function combine(k: M3, s: number, c: number): M3 {
  // I + s·K + c·K²
  const k2 = mm(k, k);
  return [0, 1, 2].map((i) => [0, 1, 2].map((j) => (i === j ? 1 : 0) + s * k[i][j] + c * k2[i][j]));
}

/** Smallest rotation turning direction u onto v (Rodrigues); half a turn about a perpendicular axis when opposite. */
export function minRotation(u: V3, v: V3): M3 {
  u = scale(u, 1 / Math.max(norm(u), 1e-12));
  v = scale(v, 1 / Math.max(norm(v), 1e-12));
  const axis = cross(u, v);
  const s2 = dot(axis, axis);
  const c = dot(u, v);
  if (s2 <= 1e-24) {
    if (c > 0) return eye3();
    let perp = cross(u, [1, 0, 0]);
    if (norm(perp) < 1e-6) perp = cross(u, [0, 1, 0]);
    perp = scale(perp, 1 / norm(perp));
    return [0, 1, 2].map((i) => [0, 1, 2].map((j) => 2 * perp[i] * perp[j] - (i === j ? 1 : 0)));
  }
  return combine(skew(axis), 1, (1 - c) / s2);
}

function torso(up: V3, side: V3): M3 | null {
  const nu = norm(up);
  if (nu < 1e-12) return null;
  const y = scale(up, 1 / nu);
  let x = sub(side, scale(y, dot(side, y)));
  const nx = norm(x);
  if (nx < 1e-12) return null;
  x = scale(x, 1 / nx);
  const z = cross(x, y);
  return [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]];
}

function twisted(w: M3, restSide: V3, bone: V3, side: V3): M3 {
  const axis = scale(bone, 1 / Math.max(norm(bone), 1e-12));
  let a = mv(w, restSide);
  a = sub(a, scale(axis, dot(a, axis)));
  const b = sub(side, scale(axis, dot(side, axis)));
  if (norm(a) <= 1e-9 || norm(b) <= 1e-9) return w;
  const angle = Math.atan2(dot(cross(a, b), axis), dot(a, b));
  return mm(combine(skew(axis), Math.sin(angle), 1 - Math.cos(angle)), w);
}

export function affineInverse(m: M4): M4 {
  const a = m;
  const inv = [
    [a[1][1] * a[2][2] - a[1][2] * a[2][1], a[0][2] * a[2][1] - a[0][1] * a[2][2], a[0][1] * a[1][2] - a[0][2] * a[1][1]],
    [a[1][2] * a[2][0] - a[1][0] * a[2][2], a[0][0] * a[2][2] - a[0][2] * a[2][0], a[0][2] * a[1][0] - a[0][0] * a[1][2]],
    [a[1][0] * a[2][1] - a[1][1] * a[2][0], a[0][1] * a[2][0] - a[0][0] * a[2][1], a[0][0] * a[1][1] - a[0][1] * a[1][0]],
  ];
  const det = a[0][0] * inv[0][0] + a[0][1] * inv[1][0] + a[0][2] * inv[2][0];
  const r = inv.map((row) => row.map((x) => x / det));
  const t = mv(r, [m[0][3], m[1][3], m[2][3]]);
  return [[...r[0], -t[0]], [...r[1], -t[1]], [...r[2], -t[2]], [0, 0, 0, 1]];
}

/** Median hip → knee → ankle length of the tracked legs in one frame (null if no leg is tracked). */
function legLength(p: (V3 | null)[], ok: boolean[]): number | null {
  const lengths: number[] = [];
  for (const [h, k, a] of [[K.HipLeft, K.KneeLeft, K.AnkleLeft], [K.HipRight, K.KneeRight, K.AnkleRight]]) {
    if (ok[h] && ok[k] && ok[a]) lengths.push(norm(sub(p[h]!, p[k]!)) + norm(sub(p[k]!, p[a]!)));
  }
  if (!lengths.length) return null;
  lengths.sort((x, y) => x - y);
  return lengths.length % 2 ? lengths[(lengths.length - 1) / 2] : 0.5 * (lengths[0] + lengths[1]);
}

export class Retargeter {
  private last: M3[];
  private hipReference: V3 | null = null;
  private displacement: V3 = [0, 0, 0];
  /** Avatar leg length / tracked leg length; from the first frame with a tracked leg unless set. */
  ratio: number | null;
  private readonly mover: number;

  constructor(readonly plan: RetargetPlan, ratio: number | null = null) {
    this.last = plan.order.map(() => eye3());
    this.ratio = ratio;
    let j = plan.root;
    while (plan.parents[j] >= 0) j = plan.parents[j];
    this.mover = j;
  }

  /** Back to the bind pose and a new travel origin (a new person, or the avatar replaced). */
  reset(): void {
    this.last = this.plan.order.map(() => eye3());
    this.hipReference = null;
    this.displacement = [0, 0, 0];
  }

  /** One frame of Kinect-20 positions (metres, +Y up, facing +Z; null or untracked rows are ignored). */
  frame(positions: (V3 | null)[], tracked: boolean[]): AvatarFrame {
    const plan = this.plan;
    const ok = tracked.map((t, i) => t && positions[i] !== null && positions[i]!.every(Number.isFinite));
    const src: V3[] = positions.map((p, i) => (ok[i] ? mv(plan.align, p!) : [0, 0, 0]));
    if (this.ratio === null) {
      const leg = legLength(positions, ok);
      if (leg !== null && leg > 0) this.ratio = plan.leg_length / leg;
    }
    if (ok[K.HipCenter]) {
      if (this.hipReference === null) this.hipReference = src[K.HipCenter];
      if (this.ratio !== null) this.displacement = scale(sub(src[K.HipCenter], this.hipReference), this.ratio);
    }
    const n = plan.order.length;
    const rot: M3[] = new Array(n);
    const world: M4[] = new Array(n);
    const shOk = ok[K.ShoulderLeft] && ok[K.ShoulderRight];
    const shoulders = sub(src[K.ShoulderRight], src[K.ShoulderLeft]);
    for (const j of plan.order) {
      const vp = plan.parents[j];
      const parent = vp < 0 ? eye3() : rot[vp];
      let w: M3 | null = null;
      if (j === plan.root) {
        let side: V3 = [0, 0, 0];
        let pairs = 0;
        if (ok[K.HipLeft] && ok[K.HipRight]) { side = add(side, sub(src[K.HipRight], src[K.HipLeft])); pairs++; }
        if (shOk) { side = add(side, shoulders); pairs++; }
        if (ok[K.HipCenter] && ok[K.ShoulderCenter] && pairs > 0) {
          const frame = torso(sub(src[K.ShoulderCenter], src[K.HipCenter]), side);
          if (frame) w = mm(frame, transpose(plan.root_frame));
        }
      } else if (plan.aim_from[j] >= 0) {
        const a = plan.aim_from[j], b = plan.aim_to[j];
        const s = sub(src[b], src[a]);
        if (ok[a] && ok[b] && norm(s) > 1e-9) {
          w = mm(minRotation(mv(parent, plan.rest_aim[j]), s), parent);
          if (plan.twist[j] && shOk) w = twisted(w, plan.rest_shoulders, s, shoulders);
        }
      }
      if (w) this.last[j] = mm(transpose(parent), w);
      rot[j] = mm(parent, this.last[j]);
      const lin = mm(rot[j], plan.bind_linear[j]);
      let t: V3;
      if (vp < 0) {
        t = plan.bind_positions[j];
        if (j === this.mover) t = add(t, this.displacement);
      } else {
        t = add([world[vp][0][3], world[vp][1][3], world[vp][2][3]],
          mv(parent, sub(plan.bind_positions[j], plan.bind_positions[vp])));
      }
      world[j] = [[...lin[0], t[0]], [...lin[1], t[1]], [...lin[2], t[2]], [0, 0, 0, 1]];
    }
    const local = world.map((m, j) => {
      const rp = plan.real_parents[j];
      const above = rp < 0 ? plan.fixed_parent[j] : mm(world[rp], plan.fixed_parent[j]);
      return mm(affineInverse(above), m);
    });
    return { world, local, rotations: rot };
  }
}
