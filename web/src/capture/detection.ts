// What the landmark worker (landmarks.worker.ts) and the page say to each other.

export interface Landmark {
  x: number;
  y: number;
  z: number;
  visibility?: number;
}

export interface PoseLandmarks {
  world: Landmark[]; // 33 landmarks, metres, hip-centred, +Y down
  image: Landmark[]; // 33 landmarks, x and y normalised to the image's width and height
}

export interface HandLandmarks {
  handedness: string; // "Left" or "Right"
  world: Landmark[]; // 21 landmarks, metres
  image: Landmark[];
}

export interface FaceBlendshapes {
  scores: Record<string, number>; // the 52 ARKit-named blendshapes, 0..1
}

/** Which landmarkers run on each frame. */
export interface Features {
  hands: boolean;
  face: boolean;
  tiles?: boolean; // also search a wide frame's overlapping squares for small people (default on)
}

export type WorkerRequest =
  | { type: 'init'; wasm: string; models: string; delegate: 'auto' | 'CPU' | 'GPU'; numPoses: number; features: Features }
  | { type: 'frame'; bitmap: ImageBitmap; t: number }
  | { type: 'features'; features: Features };

export interface Detection {
  t: number; // the frame's capture time (performance.now() on the page)
  ms: number; // milliseconds the worker spent on it
  width: number;
  height: number;
  poses: PoseLandmarks[]; // distinct people, best first
  searches: number; // pose searches run on it: the whole frame, plus the squares of a wide one
  hands: HandLandmarks[];
  faces: FaceBlendshapes[];
}

export type WorkerReply =
  | { type: 'ready'; delegate: 'CPU' | 'GPU' }
  | ({ type: 'detection' } & Detection)
  | { type: 'error'; message: string };

export const MODEL_FILES = {
  pose: 'pose_landmarker_full.task',
  hand: 'hand_landmarker.task',
  face: 'face_landmarker.task',
} as const;
