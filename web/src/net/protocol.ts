// The studio wire format: JSON messages (src/kinetre/studio/protocol.py) and binary transform blocks (src/kinetre/wire/transforms.py).
import type { MotionQuality } from '../app/QualityMeter';

export type Vec3 = [number, number, number];

export interface SkeletonMessage {
  type: 'skeleton';
  client?: string;
  seq: number;
  t: number;
  model: string;
  positions: (Vec3 | null)[];
  tracked: boolean[];
  hands?: (Vec3[] | null)[]; // [left, right], see handsFace.ts
  blendshapes?: number[] | null;
}

export interface UserState {
  client: string;
  possessing: boolean;
  mesh?: number | null; // the id of the mesh it possesses
  subset: string | string[] | null;
  hand?: 'left' | 'right' | null; // the hand that possesses (a hand puppet), null for the body
  frames: number;
  attached: number[];
  quality?: MotionQuality | null; // the live motion meter (app/QualityMeter.ts); absent from older servers
  cleaning?: string[]; // what cleans its body frames before the solve: "smoothing", "contact" (none: as sent)
}

export interface PlacementState {
  scale: number;
  position: Vec3;
  yaw: number;
  matrix: number[]; // column-major 4x4, as three.js Matrix4.elements
}

export interface MeshInfo {
  id: number;
  name: string;
  url: string;
  nodes: number;
  vertices: number;
  up?: string;
  up_reason?: string;
}

/** One of the scene's meshes: where it stands and who possesses it. */
export interface MeshState extends MeshInfo {
  placement: PlacementState;
  possessors: string[];
  solve_ms: number | null;
}

export interface SceneState {
  type: 'state';
  meshes: MeshState[]; // every mesh of the scene, in its order (none while a remote scene is not heard yet)
  users: UserState[];
  recording: boolean;
  joint_map?: { name: string; sources: number } | null;
  solve_ms: number | null;
  error: string;
  scene_lost?: boolean; // set by a studio whose remote scene stopped answering (no meshes if never heard)
}

export type ServerMessage =
  | { type: 'welcome'; client: string; channel: string; resume?: string }
  | SceneState
  | SkeletonMessage
  | { type: 'error'; message: string }
  | { type: 'stats'; client: string; received: number; malformed: number; last_seq: number };

export interface TransformBlock {
  seq: number;
  meshId: number;
  count: number;
  tSource: number;
  tOut: number;
  rows: Float32Array; // count × 12: the top three rows of each node matrix, row-major
}

const HEADER_BYTES = 32;

/** Decode a "KTX1" block; null when the bytes are not one. */
export function decodeTransforms(buffer: ArrayBuffer): TransformBlock | null {
  if (buffer.byteLength < HEADER_BYTES) return null;
  const view = new DataView(buffer);
  const magic = String.fromCharCode(view.getUint8(0), view.getUint8(1), view.getUint8(2), view.getUint8(3));
  const count = view.getUint32(12, true);
  if (magic !== 'KTX1' || buffer.byteLength !== HEADER_BYTES + 48 * count) return null;
  return {
    seq: view.getUint32(4, true),
    meshId: view.getUint32(8, true),
    count,
    tSource: view.getFloat64(16, true),
    tOut: view.getFloat64(24, true),
    rows: new Float32Array(buffer, HEADER_BYTES, count * 12),
  };
}
