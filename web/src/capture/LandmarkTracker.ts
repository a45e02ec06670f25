// The page's side of the landmark worker: hands it the camera's newest frame whenever it is idle and
// drops the frames in between, so the page renders at its own rate and never waits on detection.
import type { Detection, Features, WorkerReply, WorkerRequest } from './detection';

export interface TrackerOptions {
  wasm: string; // URL of the folder holding tasks-vision's wasm files
  models: string; // URL of the folder holding the .task models
  delegate: 'auto' | 'CPU' | 'GPU';
  numPoses: number;
  features: Features;
}

export class LandmarkTracker {
  private worker: Worker | null = null;
  private ready: Promise<void> | null = null;
  private busy = false;
  private lastVideoTime = -1;
  /** The delegate the worker runs on, once ready. */
  delegate: 'CPU' | 'GPU' | null = null;
  /** Milliseconds the worker spent on the last frame, and detections so far. */
  detectMs = 0;
  detections = 0;
  dropped = 0;
  onDetection: (d: Detection) => void = () => {};
  onError: (message: string) => void = () => {};

  constructor(private readonly options: TrackerOptions) {}

  init(): Promise<void> {
    if (this.ready) return this.ready;
    const worker = new Worker(new URL('./landmarks.worker.ts', import.meta.url), { type: 'classic' });
    this.worker = worker;
    this.ready = new Promise((resolve, reject) => {
      worker.onmessage = (event: MessageEvent<WorkerReply>) => {
        const reply = event.data;
        if (reply.type === 'ready') {
          this.delegate = reply.delegate;
          resolve();
        } else if (reply.type === 'error') {
          this.busy = false;
          if (!this.delegate) reject(new Error(`pose tracker: ${reply.message}`));
          else this.onError(reply.message);
        } else {
          this.busy = false;
          this.detectMs = reply.ms;
          this.detections++;
          this.onDetection(reply);
        }
      };
      worker.onerror = (e) => reject(new Error(`pose tracker: ${e.message || 'the worker failed to load'}`));
    });
    const { wasm, models, delegate, numPoses, features } = this.options;
    this.send({ type: 'init', wasm, models, delegate, numPoses, features });
    this.ready.catch(() => this.dispose());
    return this.ready;
  }

  setFeatures(features: Features): void {
    this.options.features = features;
    if (this.worker) this.send({ type: 'features', features });
  }

  /** Offer the video's current frame; taken only when the worker is idle and the frame is new. */
  async offer(video: HTMLVideoElement): Promise<boolean> {
    if (!this.worker || !this.delegate || video.readyState < 2 || video.currentTime === this.lastVideoTime) return false;
    if (this.busy) {
      this.dropped++;
      return false;
    }
    this.busy = true;
    this.lastVideoTime = video.currentTime;
    const t = performance.now();
    try {
      const bitmap = await createImageBitmap(video);
      this.send({ type: 'frame', bitmap, t }, [bitmap]);
      return true;
    } catch {
      this.busy = false; // the video changed size or stopped between the check and the grab
      return false;
    }
  }

  dispose(): void {
    this.worker?.terminate();
    this.worker = null;
    this.ready = null;
    this.delegate = null;
    this.busy = false;
  }

  private send(request: WorkerRequest, transfer: Transferable[] = []): void {
    this.worker?.postMessage(request, transfer);
  }
}
