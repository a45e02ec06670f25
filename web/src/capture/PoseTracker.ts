// MediaPipe Pose on the camera video, run from the files copied next to the page (no CDN).
// @mediapipe/pose is a classic script that defines window.Pose; it is loaded on first use.
import type { NormalizedLandmark, Options, Pose, Results } from '@mediapipe/pose';

type PoseConstructor = new (config: { locateFile: (file: string) => string }) => Pose;

export interface PoseResult {
  world: NormalizedLandmark[];
  image: NormalizedLandmark[];
}

/** Load a classic script once (the MediaPipe solutions define their class on window). */
export function loadScript(src: string): Promise<void> {
  return new Promise((resolve, reject) => {
    const script = document.createElement('script');
    script.src = src;
    script.onload = () => resolve();
    script.onerror = () => reject(new Error(`cannot load ${src}`));
    document.head.appendChild(script);
  });
}

export class PoseTracker {
  private pose: Pose | null = null;
  private latest: PoseResult | null | undefined;
  /** Milliseconds per detection, for the status line. */
  detectMs = 0;

  constructor(private readonly base = 'mediapipe/pose/', private readonly options: Options = {
    modelComplexity: 0, // the lite model: real time on a laptop CPU, and bearable on SwiftShader
    smoothLandmarks: true,
    enableSegmentation: false,
    minDetectionConfidence: 0.5,
    minTrackingConfidence: 0.5,
  }) {}

  async init(): Promise<void> {
    if (this.pose) return;
    const w = window as unknown as { Pose?: PoseConstructor };
    if (!w.Pose) await loadScript(`${this.base}pose.js`);
    if (!w.Pose) throw new Error('PoseTracker: pose.js did not define Pose');
    const pose = new w.Pose({ locateFile: (file) => `${this.base}${file}` });
    pose.setOptions(this.options);
    pose.onResults((r: Results) => {
      this.latest = r.poseWorldLandmarks && r.poseLandmarks
        ? { world: r.poseWorldLandmarks, image: r.poseLandmarks }
        : null;
    });
    await pose.initialize();
    this.pose = pose;
  }

  /** Detect the pose in the current video frame; null when nobody is found (tracking lost). */
  async detect(video: HTMLVideoElement): Promise<PoseResult | null> {
    if (!this.pose) throw new Error('PoseTracker: call init() first');
    const start = performance.now();
    this.latest = undefined;
    await this.pose.send({ image: video });
    this.detectMs = performance.now() - start;
    return this.latest ?? null;
  }
}
