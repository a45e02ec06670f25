// MediaPipe Pose (33 landmarks) → Kinect 20 in the studio's frame: metres, +Y up, +Z toward the
// camera. World landmarks are hip-centred with +Y down, so the root translation (walking, jumping) is
// recovered from the image: depth from the apparent torso length, x/y from where the hips are in the image.
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

  /** Hip-centre position in the studio: from the image position of the hips and the torso's apparent size. */
  private rootTranslation(world: NormalizedLandmark[], image: NormalizedLandmark[]): Vec3 {
    const mid = (a: NormalizedLandmark, b: NormalizedLandmark) => ({ x: (a.x + b.x) / 2, y: (a.y + b.y) / 2, z: (a.z + b.z) / 2 });
    const hipW = mid(world[23], world[24]), shW = mid(world[11], world[12]);
    const hipI = mid(image[23], image[24]), shI = mid(image[11], image[12]);
    const torsoWorld = Math.hypot(shW.x - hipW.x, shW.y - hipW.y, shW.z - hipW.z);
    // image coordinates are normalised by width (x) and height (y): bring both to width units
    const torsoImage = Math.hypot(shI.x - hipI.x, (shI.y - hipI.y) / this.aspect);
    const depth = torsoImage > 1e-3 ? (FOCAL * torsoWorld) / torsoImage : STAGE_DISTANCE;
    const x = ((hipI.x - 0.5) * depth) / FOCAL;
    const y = (-(hipI.y - 0.5) / this.aspect) * depth / FOCAL;
    if (this.cameraHeight === null) {
      const feet = [27, 28, 31, 32].filter((i) => (world[i].visibility ?? 1) >= VISIBLE);
      if (feet.length >= 2) {
        const lowest = Math.max(...feet.map((i) => world[i].y)); // +Y down: the largest is the lowest
        this.cameraHeight = lowest - y; // puts the lowest visible foot on the floor (y = 0)
      }
    }
    return [x, y + (this.cameraHeight ?? 1.0), STAGE_DISTANCE - depth];
  }

  /** Forget the floor calibration (a new person, or the camera moved). */
  recalibrate(): void {
    this.cameraHeight = null;
  }
}
