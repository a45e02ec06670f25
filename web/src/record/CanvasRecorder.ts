// The 3D view as a WebM video (MediaRecorder on the canvas stream), for sharing a take as it looked.

export class CanvasRecorder {
  private recorder: MediaRecorder | null = null;
  private chunks: Blob[] = [];

  constructor(private readonly canvas: HTMLCanvasElement, private readonly fps = 30) {}

  get recording(): boolean {
    return this.recorder !== null;
  }

  start(): void {
    if (this.recorder) return;
    const type = ['video/webm;codecs=vp9', 'video/webm;codecs=vp8', 'video/webm'].find((t) => MediaRecorder.isTypeSupported(t));
    this.chunks = [];
    this.recorder = new MediaRecorder(this.canvas.captureStream(this.fps), type ? { mimeType: type } : undefined);
    this.recorder.ondataavailable = (e) => { if (e.data.size) this.chunks.push(e.data); };
    this.recorder.start(250);
  }

  /** Stops and resolves with the video (null when nothing was recorded). */
  stop(): Promise<Blob | null> {
    const recorder = this.recorder;
    this.recorder = null;
    if (!recorder) return Promise.resolve(null);
    return new Promise((resolve) => {
      recorder.onstop = () => resolve(this.chunks.length ? new Blob(this.chunks, { type: 'video/webm' }) : null);
      recorder.stop();
    });
  }
}
