// Tracked hands on an avatar's finger bones: the page's side of src/kinetre/avatar/fingers.py (which joints
// are the fingers) and retarget.py `retarget_fingers` (Algorithm 1 per finger segment); a Python test runs
// both on one fixture and compares the numbers.
//
// Chains come from the VRM humanoid's finger bones, else from the joints below each mapped elbow whose name
// holds a finger's word, each the child of the one before. Each finger bone (chain joint → the next one;
// the last → its child node, a tip without one is left alone) follows one segment of MediaPipe's finger,
// the first bone the first segment and the last the last: q_world = minrot(q_parent d_i → s) · q_parent.
// A bone whose hand is not seen keeps its last local rotation (at first the bind pose); joints below the
// fingers are carried along. Plain arrays, as retarget.ts.
import {
  affineInverse, add, eye3, minRotation, mm, mv, norm, sub, transpose,
  type AvatarFrame, type M3, type M4, type RetargetPlan, type V3,
} from './retarget';

export const SIDES = ['Left', 'Right'] as const;
/** MediaPipe hand landmarks of each finger from the palm out (skeleton/mediapipe.py FINGERS). */
export const FINGERS: Record<string, number[]> = {
  thumb: [1, 2, 3, 4], index: [5, 6, 7, 8], middle: [9, 10, 11, 12], ring: [13, 14, 15, 16], little: [17, 18, 19, 20],
};
const WORDS: Record<string, string[]> = {
  thumb: ['thumb'], index: ['index', 'pointer'], middle: ['middle', 'mid'], ring: ['ring'], little: ['pinky', 'little', 'small'],
};
const VRM_PARTS = ['Metacarpal', 'Proximal', 'Intermediate', 'Distal'];

export interface FingerChain {
  side: number; // 0 left, 1 right
  finger: string; // a key of FINGERS
  joints: number[]; // from the palm out
}

/** One hand: 21 landmarks in the studio's frame (metres, +Y up, facing +Z), or null when not seen. */
export type Hand = (V3 | null)[] | null;

/**
 * The avatar's finger chains. names and parents: its joints and each one's parent joint (-1 at a root);
 * vrmBones: VRM humanoid bone name → joint; map: Kinect-20 joint name → joint (the body's bone map).
 */
export function fingerChains(names: string[], parents: number[], vrmBones: Record<string, number>,
  map: Record<string, number>): FingerChain[] {
  const chains: FingerChain[] = [];
  SIDES.forEach((s, side) => {
    for (const finger of Object.keys(FINGERS)) {
      const title = finger[0].toUpperCase() + finger.slice(1);
      const vrm = VRM_PARTS.map((part) => vrmBones[`${s.toLowerCase()}${title}${part}`]).filter((j) => j !== undefined);
      const arm = map[`Elbow${s}`] ?? map[`Wrist${s}`];
      const joints = vrm.length ? vrm : namedChain(names, parents, arm, finger);
      if (joints.length) chains.push({ side, finger, joints });
    }
  });
  return chains;
}

function namedChain(names: string[], parents: number[], arm: number | undefined, finger: string): number[] {
  if (arm === undefined) return [];
  const found: [number, number][] = [];
  names.forEach((name, j) => {
    const depth = depthBelow(parents, j, arm);
    if (depth === null) return;
    const tokens = name.replace(/([a-z])([A-Z])/g, '$1 $2').toLowerCase().match(/[a-z]+/g) ?? [];
    if (tokens.some((t) => WORDS[finger].some((w) => t.startsWith(w)))) found.push([depth, j]); // "Index1", "pinky_01"
  });
  found.sort((a, b) => a[0] - b[0] || a[1] - b[1]);
  const chain: number[] = [];
  for (const [, j] of found) if (!chain.length || parents[j] === chain[chain.length - 1]) chain.push(j);
  return chain;
}

function depthBelow(parents: number[], j: number, ancestor: number): number | null {
  let depth = 0;
  for (let k = j; k >= 0; k = parents[k], depth++) if (k === ancestor) return depth > 0 ? depth : null;
  return null;
}

/** Python's round (half to even), so that bones pick the same segments on both sides. */
function roundHalfEven(x: number): number {
  const r = Math.round(x);
  return Math.abs(x % 1) === 0.5 && r % 2 !== 0 ? r - 1 : r;
}

interface Aim { rest: V3; side: number; from: number; to: number }

export class FingerRetargeter {
  private readonly aims = new Map<number, Aim>();
  private last = new Map<number, M3>();

  /**
   * tipEnd(j): the bind-pose position (the avatar's frame) of the child node of chain end joint j, or null
   * when it has none (that bone is then left alone).
   */
  constructor(readonly plan: RetargetPlan, chains: FingerChain[], tipEnd: (joint: number) => V3 | null) {
    const p = plan.bind_positions;
    for (const { side, finger, joints } of chains) {
      const bones: [number, V3][] = [];
      joints.forEach((j, i) => {
        const end = i + 1 < joints.length ? p[joints[i + 1]] : tipEnd(j);
        if (!end) return;
        const d = sub(end, p[j]);
        const n = norm(d);
        if (n > 1e-12) bones.push([j, d.map((x) => x / n)]);
      });
      const marks = FINGERS[finger];
      bones.forEach(([j, rest], b) => {
        const k = roundHalfEven((b * (marks.length - 2)) / Math.max(bones.length - 1, 1));
        this.aims.set(j, { rest, side, from: marks[k], to: marks[k + 1] });
      });
    }
  }

  /** True when the avatar has finger bones to drive. */
  get active(): boolean {
    return this.aims.size > 0;
  }

  /** The finger bones driven (joint indices). */
  get joints(): number[] {
    return [...this.aims.keys()];
  }

  /** Back to the bind pose of the fingers. */
  reset(): void {
    this.last = new Map();
  }

  /** The body's frame (Retargeter.frame) with the finger bones following hands [left, right]. */
  frame(body: AvatarFrame, hands: Hand[]): AvatarFrame {
    const plan = this.plan;
    if (!this.aims.size) return body;
    const p = plan.bind_positions;
    const rot = [...body.rotations];
    const world = [...body.world];
    const moved = new Array(plan.order.length).fill(false);
    for (const j of plan.order) {
      const vp = plan.parents[j];
      const aim = this.aims.get(j);
      if (!aim && !(vp >= 0 && moved[vp])) continue;
      moved[j] = true;
      const parent = vp < 0 ? eye3() : rot[vp];
      let relative: M3;
      if (aim) {
        const hand = hands[aim.side];
        const a = hand?.[aim.from], b = hand?.[aim.to];
        if (a && b && [...a, ...b].every(Number.isFinite)) {
          const s = mv(plan.align, sub(b, a));
          if (norm(s) > 1e-9) {
            const w = mm(minRotation(mv(parent, aim.rest), s), parent);
            this.last.set(j, mm(transpose(parent), w));
          }
        }
        relative = this.last.get(j) ?? eye3();
      } else {
        relative = mm(transpose(body.rotations[vp]), body.rotations[j]); // carried along
      }
      rot[j] = mm(parent, relative);
      const lin = mm(rot[j], plan.bind_linear[j]);
      const t: V3 = vp < 0 ? [world[j][0][3], world[j][1][3], world[j][2][3]]
        : add([world[vp][0][3], world[vp][1][3], world[vp][2][3]], mv(rot[vp], sub(p[j], p[vp])));
      world[j] = [[...lin[0], t[0]], [...lin[1], t[1]], [...lin[2], t[2]], [0, 0, 0, 1]];
    }
    const local: M4[] = body.local.map((l, j) => {
      const rp = plan.real_parents[j];
      if (!moved[j] && !(rp >= 0 && moved[rp])) return l;
      const above = rp < 0 ? plan.fixed_parent[j] : mm(world[rp], plan.fixed_parent[j]);
      return mm(affineInverse(above), world[j]);
    });
    return { world, local, rotations: rot };
  }
}
