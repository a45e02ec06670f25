// Which detected hands are a person's left and right, and where they are in the studio's frame. As the
// capture on the Python side (motion/capture.py): a hand belongs to the wrist its landmark 0 starts at
// (the least summed image distance, no farther than the hand's own size); its world landmarks, flipped to
// +Y up and +Z toward the camera, are placed with landmark 0 at the body's wrist.
import type { HandLandmarks, Landmark, PoseLandmarks } from './detection';
import type { KinectFrame } from './KinectMapper';
import { KINECT20_JOINTS } from './kinect20';
import type { Vec3 } from '../net/protocol';

const WRIST_LANDMARKS = [15, 16]; // MediaPipe Pose's left and right wrist
const WRIST_JOINTS = [KINECT20_JOINTS.indexOf('WristLeft'), KINECT20_JOINTS.indexOf('WristRight')];

/** 21 landmarks in the studio's frame, or null when that hand is not seen. */
export type PersonHand = Vec3[] | null;

/** The person's [left, right] hands among `hands` (image landmarks normalised; aspect = width / height). */
export function personHands(pose: PoseLandmarks, frame: KinectFrame, hands: HandLandmarks[], aspect: number): PersonHand[] {
  const px = (l: Landmark): [number, number] => [l.x * aspect, l.y];
  const cost = hands.map((h) => {
    const xs = h.image.map((l) => px(l)[0]), ys = h.image.map((l) => px(l)[1]);
    const size = Math.max(Math.max(...xs) - Math.min(...xs), Math.max(...ys) - Math.min(...ys), 1e-6);
    const start = px(h.image[0]);
    return WRIST_LANDMARKS.map((w) => {
      const [x, y] = px(pose.image[w]);
      return Math.hypot(start[0] - x, start[1] - y) / size;
    });
  });
  // two slots: try every pair of distinct hands (or none) for them, keep the cheapest full match
  let best: [number, number] = [-1, -1];
  let bestScore = [0, Infinity]; // [matched slots (more is better), summed cost]
  const options = [-1, ...hands.keys()];
  for (const l of options) {
    for (const r of options) {
      if (l >= 0 && l === r) continue;
      if ((l >= 0 && cost[l][0] > 1) || (r >= 0 && cost[r][1] > 1)) continue;
      const n = Number(l >= 0) + Number(r >= 0);
      const c = (l >= 0 ? cost[l][0] : 0) + (r >= 0 ? cost[r][1] : 0);
      if (n > bestScore[0] || (n === bestScore[0] && c < bestScore[1])) { best = [l, r]; bestScore = [n, c]; }
    }
  }
  return best.map((k, side) => {
    if (k < 0) return null;
    const world = hands[k].world;
    const wrist = frame.positions[WRIST_JOINTS[side]] ?? [0, 0, 0];
    return world.map((l) => [wrist[0] + (l.x - world[0].x), wrist[1] - (l.y - world[0].y), wrist[2] - (l.z - world[0].z)] as Vec3);
  });
}
