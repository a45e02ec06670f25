// MediaPipe Tasks off the page's thread: pose (several people), hands and face blendshapes on each frame the
// page hands over as an ImageBitmap. A classic worker, because the Tasks wasm loader uses importScripts.
// The GPU delegate draws into the worker's own OffscreenCanvas; software WebGL (SwiftShader) is slower
// than the wasm CPU path, so it counts as no GPU.
import { FaceLandmarker, FilesetResolver, HandLandmarker, PoseLandmarker } from '@mediapipe/tasks-vision';
import { MODEL_FILES, type Detection, type Features, type WorkerReply, type WorkerRequest } from './detection';

interface Landmarkers {
  pose: PoseLandmarker;
  hand: HandLandmarker;
  face: FaceLandmarker;
}

let landmarkers: Landmarkers | null = null;
let features: Features = { hands: true, face: true };
let lastT = -1;

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
  const [pose, hand, face] = await Promise.all([
    PoseLandmarker.createFromOptions(fileset, { baseOptions: base(MODEL_FILES.pose), runningMode: 'VIDEO', numPoses, canvas }),
    HandLandmarker.createFromOptions(fileset, { baseOptions: base(MODEL_FILES.hand), runningMode: 'VIDEO', numHands: 2, canvas }),
    FaceLandmarker.createFromOptions(fileset, {
      baseOptions: base(MODEL_FILES.face), runningMode: 'VIDEO', numFaces: 1, outputFaceBlendshapes: true, canvas,
    }),
  ]);
  return { pose, hand, face };
}

async function init(request: Extract<WorkerRequest, { type: 'init' }>): Promise<void> {
  features = request.features;
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

function detect(bitmap: ImageBitmap, t: number): Detection {
  if (!landmarkers) throw new Error('the landmark worker was sent a frame before it was ready');
  const start = performance.now();
  const at = t > lastT ? t : lastT + 0.001; // VIDEO mode wants strictly increasing timestamps
  lastT = at;
  const pose = landmarkers.pose.detectForVideo(bitmap, at);
  const detection: Detection = {
    t, ms: 0, width: bitmap.width, height: bitmap.height,
    poses: pose.landmarks.map((image, i) => ({ image, world: pose.worldLandmarks[i] })),
    hands: [],
    faces: [],
  };
  if (features.hands) {
    const hands = landmarkers.hand.detectForVideo(bitmap, at);
    detection.hands = hands.landmarks.map((image, i) => ({
      image, world: hands.worldLandmarks[i], handedness: hands.handedness[i]?.[0]?.categoryName ?? '',
    }));
  }
  if (features.face) {
    const face = landmarkers.face.detectForVideo(bitmap, at);
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
    else if (request.type === 'features') features = request.features;
    else {
      try {
        post({ type: 'detection', ...detect(request.bitmap, request.t) });
      } finally {
        request.bitmap.close();
      }
    }
  } catch (err) {
    post({ type: 'error', message: (err as Error).message ?? String(err) });
  }
};
