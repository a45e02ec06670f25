// MediaPipe Tasks off the page's thread: pose (several people), hands and face blendshapes on each frame the
// page hands over as an ImageBitmap. A classic worker, because the Tasks wasm loader uses importScripts.
// The GPU delegate draws into the worker's own OffscreenCanvas; software WebGL (SwiftShader) is slower
// than the wasm CPU path, so it counts as no GPU.
//
// Only the whole frame's PoseLandmarker is made before the worker says it is ready: each landmarker takes
// seconds to make under SwiftShader, and a detection costs the sum of the landmarkers it runs. Every other
// one is made in the background when first wanted, and the frames meanwhile go without it: the hand and face
// landmarkers when the page asks for hands or a face (`features`: an avatar, the face puppet or a hand
// puppet), a square's PoseLandmarker when its search is first due.
//
// Bodies in a wide frame are also looked for in its overlapping squares (tiles.ts), each square with a
// PoseLandmarker of its own (VIDEO mode follows what it found in the previous frame of the same stream).
// Squares are searched only after the whole frame has been searched for a few frames (the first person is
// found by the whole frame, without waiting for squares) and only while it finds fewer than `numPoses`
// people. To keep detections coming at nearly the rate of the whole frame's, a frame searches the whole
// frame and every square that last found someone the whole frame missed; every DISCOVER_EVERY-th frame also
// searches one more square in turn, so a small person is found within DISCOVER_EVERY frames per square, then
// followed every frame. Hands and faces are looked for in the whole frame only.
import { FaceLandmarker, FilesetResolver, HandLandmarker, PoseLandmarker, type PoseLandmarkerResult } from '@mediapipe/tasks-vision';
import { MODEL_FILES, type Detection, type Features, type PoseLandmarks, type WorkerReply, type WorkerRequest } from './detection';
import { distinct, pixels, repeats, squareTiles, toImage, type Tile } from './tiles';

/** A landmarker made in the background on its first `get`: null until it is ready. */
class Later<T> {
  private value: T | null = null;
  private asked = false;

  constructor(private readonly name: string, private readonly make: () => Promise<T>) {}

  get(): T | null {
    if (!this.asked) {
      this.asked = true;
      this.make().then((v) => { this.value = v; },
        (err) => post({ type: 'error', message: `${this.name}: ${(err as Error).message ?? String(err)}` }));
    }
    return this.value;
  }
}

interface Landmarkers {
  pose: PoseLandmarker;
  hand: Later<HandLandmarker>;
  face: Later<FaceLandmarker>;
  /** A PoseLandmarker for a square (made when its search is first due). */
  squarePose: () => Later<PoseLandmarker>;
  numPoses: number;
}

/** A square of the frame and what its search found last time it ran. */
interface Square {
  pose: Later<PoseLandmarker>;
  holdsSomeone: boolean; // found a person the whole frame missed: searched every frame
}

let landmarkers: Landmarkers | null = null;
let features: Features = { hands: true, face: true, tiles: true };
let lastT = -1;
const squares: Square[] = [];
let nextSquare = 0; // the square the next discovering frame searches in turn
let framesSearched = 0;
// one discovery search in this many frames: a square costs as much as the whole frame, and searching one
// every frame halved the detection rate under SwiftShader
const DISCOVER_EVERY = 4;
// whole-frame searches before the first square's: the first person is tracked without waiting for squares
const SQUARES_FROM_FRAME = 2;
// the page searches squares from a 16:9 frame on, where the letterbox shrinks a person to 56 %; a 4:3
// webcam's letterbox keeps 75 %, and its two squares, each most of the frame, mostly find the same person
// again at a third of the detection rate
const WIDE = 1.7;

const post = (reply: WorkerReply, transfer: Transferable[] = []) => (self as unknown as Worker).postMessage(reply, transfer);

function hasHardwareGpu(): boolean {
  if (typeof OffscreenCanvas === 'undefined') return false;
  const gl = new OffscreenCanvas(1, 1).getContext('webgl2');
  if (!gl) return false;
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  const renderer = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : '';
  return !/swiftshader|llvmpipe|software/i.test(renderer);
}

async function create(wasm: string, models: string, delegate: 'CPU' | 'GPU', numPoses: number): Promise<Landmarkers> {
  const fileset = await FilesetResolver.forVisionTasks(wasm);
  const base = (file: string) => ({ modelAssetPath: models + file, delegate });
  const canvas = delegate === 'GPU' ? new OffscreenCanvas(1, 1) : undefined;
  const makePose = () => PoseLandmarker.createFromOptions(fileset,
    { baseOptions: base(MODEL_FILES.pose), runningMode: 'VIDEO', numPoses, canvas });
  const pose = await makePose();
  const hand = new Later('hand landmarker', () => HandLandmarker.createFromOptions(fileset,
    { baseOptions: base(MODEL_FILES.hand), runningMode: 'VIDEO', numHands: 2, canvas }));
  const face = new Later('face landmarker', () => FaceLandmarker.createFromOptions(fileset, {
    baseOptions: base(MODEL_FILES.face), runningMode: 'VIDEO', numFaces: 1, outputFaceBlendshapes: true, canvas,
  }));
  return { pose, hand, face, squarePose: () => new Later('square pose landmarker', makePose), numPoses };
}

async function init(request: Extract<WorkerRequest, { type: 'init' }>): Promise<void> {
  features = { tiles: true, ...request.features };
  const wanted = request.delegate === 'auto' ? (hasHardwareGpu() ? 'GPU' : 'CPU') : request.delegate;
  try {
    landmarkers = await create(request.wasm, request.models, wanted, request.numPoses);
    post({ type: 'ready', delegate: wanted });
  } catch (err) {
    if (wanted === 'CPU') throw err;
    landmarkers = await create(request.wasm, request.models, 'CPU', request.numPoses); // a GPU that would not start
    post({ type: 'ready', delegate: 'CPU' });
  }
}

/** The poses of one search, in whole-image coordinates, and each one's score (mean landmark visibility). */
function posesOf(result: PoseLandmarkerResult, tile: Tile, width: number, height: number): PoseLandmarks[] {
  return result.landmarks.map((image, i) => ({ image: toImage(tile, image, width, height), world: result.worldLandmarks[i] }));
}

const score = (p: PoseLandmarks) => p.image.reduce((sum, l) => sum + (l.visibility ?? 0), 0) / p.image.length;

/** Everyone in the frame: the whole frame's poses, and on a wide frame its squares' (see the top). */
async function bodies(marks: Landmarkers, bitmap: ImageBitmap, at: number): Promise<{ poses: PoseLandmarks[]; searches: number }> {
  const { width, height } = bitmap;
  const whole = posesOf(marks.pose.detectForVideo(bitmap, at), { x: 0, y: 0, width, height }, width, height);
  const wide = Math.max(width, height) >= WIDE * Math.min(width, height);
  const searched = framesSearched++;
  const tiles = features.tiles === false || !wide || searched < SQUARES_FROM_FRAME ? [] : squareTiles(width, height).slice(1);
  if (!tiles.length) return { poses: whole, searches: 1 };
  while (squares.length < tiles.length) squares.push({ pose: marks.squarePose(), holdsSomeone: false });
  const discover = searched % DISCOVER_EVERY === 0 && whole.length < marks.numPoses;
  const turn = discover ? nextSquare % tiles.length : -1;
  if (discover) nextSquare = turn + 1;
  const found: PoseLandmarks[] = [...whole];
  let searches = 1;
  for (const [k, tile] of tiles.entries()) {
    const square = squares[k];
    if (k !== turn && !square.holdsSomeone) continue;
    const landmarker = square.pose.get();
    if (!landmarker) continue; // still being made: searched once it is ready
    const crop = await createImageBitmap(bitmap, tile.x, tile.y, tile.width, tile.height);
    try {
      const poses = posesOf(landmarker.detectForVideo(crop, at), tile, width, height);
      searches++;
      square.holdsSomeone = poses.some((p) => !whole.some((w) => repeats(pixels(p.image, width, height), pixels(w.image, width, height))));
      found.push(...poses);
    } finally {
      crop.close();
    }
  }
  const kept = distinct(found.map((p) => pixels(p.image, width, height)), found.map(score));
  return { poses: kept.slice(0, marks.numPoses).map((i) => found[i]), searches };
}

async function detect(bitmap: ImageBitmap, t: number): Promise<Detection> {
  if (!landmarkers) throw new Error('the landmark worker was sent a frame before it was ready');
  const start = performance.now();
  const at = t > lastT ? t : lastT + 0.001; // VIDEO mode wants strictly increasing timestamps
  lastT = at;
  const { poses, searches } = await bodies(landmarkers, bitmap, at);
  const detection: Detection = {
    t, ms: 0, width: bitmap.width, height: bitmap.height, poses, searches,
    hands: [],
    faces: [],
  };
  const hand = features.hands ? landmarkers.hand.get() : null;
  if (hand) {
    const hands = hand.detectForVideo(bitmap, at);
    detection.hands = hands.landmarks.map((image, i) => ({
      image, world: hands.worldLandmarks[i], handedness: hands.handedness[i]?.[0]?.categoryName ?? '',
    }));
  }
  const faceLandmarker = features.face ? landmarkers.face.get() : null;
  if (faceLandmarker) {
    const face = faceLandmarker.detectForVideo(bitmap, at);
    detection.faces = (face.faceBlendshapes ?? []).map((b) => ({
      scores: Object.fromEntries(b.categories.map((c) => [c.categoryName, c.score])),
    }));
  }
  detection.ms = performance.now() - start;
  return detection;
}

self.onmessage = async (event: MessageEvent<WorkerRequest>) => {
  const request = event.data;
  try {
    if (request.type === 'init') await init(request);
    else if (request.type === 'features') features = { tiles: true, ...request.features };
    else {
      try {
        post({ type: 'detection', ...(await detect(request.bitmap, request.t)) });
      } finally {
        request.bitmap.close();
      }
    }
  } catch (err) {
    post({ type: 'error', message: (err as Error).message ?? String(err) });
  }
};
