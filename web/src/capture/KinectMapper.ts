// MediaPipe Pose (33 landmarks) → Kinect 20 in the studio's frame: metres, +Y up, +Z toward the
// camera. World landmarks are hip-centred with +Y down, so the root translation (walking, jumping) is
// recovered from the image: the translation that makes the world landmarks project onto the image ones
// through a pinhole, as `kinetre capture` finds it (kinetre.skeleton.mediapipe.root_translation).
import type { Landmark as NormalizedLandmark } from './detection';
import { JOINT_COUNT } from './kinect20';
import type { Vec3 } from '../net/protocol';

export interface KinectFrame {
  positions: (Vec3 | null)[];
  tracked: boolean[];
}

const VISIBLE = 0.5; // landmarks less visible than this are "not tracked"
const FOCAL = 1.0; // focal length in units of the image width (a ~53° horizontal field of view)
const STAGE_DISTANCE = 2.5; // metres from the camera to where the mesh stands (z = 0)

type Source = number | [number, number];

// Kinect joint ← landmark index, or the midpoint of two. Spine is derived afterwards.
const SOURCES: (Source | 'spine')[] = [
  [23, 24], 'spine', [11, 12], [7, 8],
  11, 13, 15, [17, 19],
  12, 14, 16, [18, 20],
  23, 25, 27, 31,
  24, 26, 28, 32,
];

export class KinectMapper {
  /** Height of the camera above the floor, fixed on the first full-body frame (the feet touch y = 0). */
  private cameraHeight: number | null = null;

  constructor(private readonly aspect = 4 / 3) {}

  map(world: NormalizedLandmark[], image: NormalizedLandmark[]): KinectFrame {
    const positions: (Vec3 | null)[] = new Array(JOINT_COUNT).fill(null);
    const tracked: boolean[] = new Array(JOINT_COUNT).fill(false);
    const root = this.rootTranslation(world, image);
    const get = (s: Source): { p: Vec3; ok: boolean } => {
      const ids = typeof s === 'number' ? [s] : s;
      const p: Vec3 = [0, 0, 0];
      let ok = true;
      for (const i of ids) {
        const l = world[i];
        p[0] += l.x / ids.length;
        p[1] -= l.y / ids.length; // +Y down → +Y up
        p[2] -= l.z / ids.length; // toward the camera is −z in MediaPipe, +z here
        ok &&= (l.visibility ?? 1) >= VISIBLE;
      }
      return { p: [p[0] + root[0], p[1] + root[1], p[2] + root[2]], ok };
    };
    SOURCES.forEach((s, j) => {
      if (s === 'spine') return;
      const { p, ok } = get(s);
      positions[j] = p;
      tracked[j] = ok;
    });
    const hip = positions[0]!, shoulders = positions[2]!;
    positions[1] = [0, 1, 2].map((k) => hip[k] + 0.25 * (shoulders[k] - hip[k])) as Vec3;
    tracked[1] = tracked[0] && tracked[2];
    return { positions: positions.map((p, j) => (tracked[j] ? p : null)), tracked };
  }

  /** Hip-centre position in the studio: the camera-space translation T of the hip-centred world landmarks
   * that projects them onto the image landmarks, in least squares over the visible ones (for each,
   * u = f (X + Tx) / (Z + Tz) is linear in T: f Tx - u Tz = u Z - f X, likewise v). Every visible landmark
   * fixes the body's size in the image, seen as the camera sees it: a torso leaning toward the camera
   * looks shorter in both, where comparing its length in metres with its length in the image read it as a
   * person metres further away. */
  private rootTranslation(world: NormalizedLandmark[], image: NormalizedLandmark[]): Vec3 {
    const [tx, ty, tz] = this.cameraTranslation(world, image) ?? this.torsoTranslation(world, image);
    const x = tx, y = -ty; // camera +Y down → studio +Y up
    if (this.cameraHeight === null) {
      const feet = [27, 28, 31, 32].filter((i) => (world[i].visibility ?? 1) >= VISIBLE);
      if (feet.length >= 2) {
        const lowest = Math.max(...feet.map((i) => world[i].y)); // +Y down: the largest is the lowest
        this.cameraHeight = lowest - y; // puts the lowest visible foot on the floor (y = 0)
      }
    }
    return [x, y + (this.cameraHeight ?? 1.0), STAGE_DISTANCE - tz];
  }

  /** T (camera axes: x right, y down, z away; metres) from the visible landmarks' 3×3 normal equations, or
   * null with fewer than 4 of them or a solution at or behind the camera. */
  private cameraTranslation(world: NormalizedLandmark[], image: NormalizedLandmark[]): Vec3 | null {
    const ata = [[0, 0, 0], [0, 0, 0], [0, 0, 0]], atb = [0, 0, 0];
    let used = 0;
    const row = (a: number[], b: number) => {
      for (let i = 0; i < 3; i++) {
        atb[i] += a[i] * b;
        for (let j = 0; j < 3; j++) ata[i][j] += a[i] * a[j];
      }
    };
    world.forEach((w, i) => {
      if ((w.visibility ?? 1) < VISIBLE || !image[i]) return;
      // image coordinates are normalised by width (x) and height (y): both in width units, about the centre
      const u = image[i].x - 0.5, v = (image[i].y - 0.5) / this.aspect;
      row([FOCAL, 0, -u], u * w.z - FOCAL * w.x);
      row([0, FOCAL, -v], v * w.z - FOCAL * w.y);
      used++;
    });
    if (used < 4) return null;
    const t = solve3(ata, atb);
    return t && t.every(Number.isFinite) && t[2] > 0 ? t : null;
  }

  /** T from the torso's length in metres against its length in the image (too few landmarks visible for
   * `cameraTranslation`), the hips where the image shows them. */
  private torsoTranslation(world: NormalizedLandmark[], image: NormalizedLandmark[]): Vec3 {
    const mid = (a: NormalizedLandmark, b: NormalizedLandmark) => ({ x: (a.x + b.x) / 2, y: (a.y + b.y) / 2, z: (a.z + b.z) / 2 });
    const hipW = mid(world[23], world[24]), shW = mid(world[11], world[12]);
    const hipI = mid(image[23], image[24]), shI = mid(image[11], image[12]);
    const torsoWorld = Math.hypot(shW.x - hipW.x, shW.y - hipW.y, shW.z - hipW.z);
    const torsoImage = Math.hypot(shI.x - hipI.x, (shI.y - hipI.y) / this.aspect);
    const depth = torsoImage > 1e-3 ? (FOCAL * torsoWorld) / torsoImage : STAGE_DISTANCE;
    return [((hipI.x - 0.5) * depth) / FOCAL, ((hipI.y - 0.5) / this.aspect) * depth / FOCAL, depth];
  }

  /** Forget the floor calibration (a new person, or the camera moved). */
  recalibrate(): void {
    this.cameraHeight = null;
  }
}

/** x with a x = b for a symmetric 3×3 `a` (Cramer's rule), or null when `a` is singular. */
function solve3(a: number[][], b: number[]): Vec3 | null {
  const det = (m: number[][]) => m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
    - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  const d = det(a);
  if (!(Math.abs(d) > 1e-12)) return null;
  return [0, 1, 2].map((k) => det(a.map((r, i) => r.map((x, j) => (j === k ? b[i] : x)))) / d) as Vec3;
}
