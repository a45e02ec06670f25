// MediaPipe Face Mesh on a video or image, from the files copied next to the page (no CDN).
// @mediapipe/face_mesh is a classic script that defines window.FaceMesh; it is loaded on first use.
import type { FaceMesh, Options, Results } from '@mediapipe/face_mesh';

type FaceMeshConstructor = new (config: { locateFile: (file: string) => string }) => FaceMesh;

export class FaceTracker {
  private mesh: FaceMesh | null = null;
  private latest: Float32Array | null | undefined;
  private size = [0, 0];
  detectMs = 0;

  constructor(private readonly base = 'mediapipe/face_mesh/', private readonly options: Options = {
    maxNumFaces: 1, refineLandmarks: false, minDetectionConfidence: 0.5, minTrackingConfidence: 0.5,
  }) {}

  async init(): Promise<void> {
    if (this.mesh) return;
    const w = window as unknown as { FaceMesh?: FaceMeshConstructor };
    if (!w.FaceMesh) await loadScript(`${this.base}face_mesh.js`);
    if (!w.FaceMesh) throw new Error('FaceTracker: face_mesh.js did not define FaceMesh');
    const mesh = new w.FaceMesh({ locateFile: (file) => `${this.base}${file}` });
    mesh.setOptions(this.options);
    mesh.onResults((r: Results) => {
      const face = r.multiFaceLandmarks?.[0];
      if (!face) { this.latest = null; return; }
      const [width, height] = this.size;
      const out = new Float32Array(468 * 3);
      for (let i = 0; i < 468; i++) {
        out[3 * i] = face[i].x * width;
        out[3 * i + 1] = face[i].y * height;
        out[3 * i + 2] = face[i].z * width;
      }
      this.latest = out;
    });
    await mesh.initialize();
    this.mesh = mesh;
  }

  /** 468 landmarks in pixels (x, y, z · width) of the current frame, or null when no face is found. */
  async detect(image: HTMLVideoElement | HTMLImageElement | HTMLCanvasElement): Promise<Float32Array | null> {
    if (!this.mesh) throw new Error('FaceTracker: call init() first');
    this.size = image instanceof HTMLVideoElement ? [image.videoWidth, image.videoHeight]
      : image instanceof HTMLImageElement ? [image.naturalWidth, image.naturalHeight] : [image.width, image.height];
    const start = performance.now();
    this.latest = undefined;
    await this.mesh.send({ image });
    this.detectMs = performance.now() - start;
    return this.latest ?? null;
  }
}

/** Load a classic script once (the MediaPipe solutions define their class on window). */
function loadScript(src: string): Promise<void> {
  return new Promise((resolve, reject) => {
    const script = document.createElement('script');
    script.src = src;
    script.onload = () => resolve();
    script.onerror = () => reject(new Error(`cannot load ${src}`));
    document.head.appendChild(script);
  });
}
