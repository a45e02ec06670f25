// A WebM built frame by frame (WebCodecs VP8 + webm-muxer) with exact timestamps k / fps: a replayed take
// becomes a video at its true speed however slowly the page renders it (MediaRecorder, by contrast,
// stamps frames with the wall clock).
import { ArrayBufferTarget, Muxer } from 'webm-muxer';

export class TakeVideo {
  private readonly muxer: Muxer<ArrayBufferTarget>;
  private readonly encoder: VideoEncoder;
  private readonly frameCanvas: OffscreenCanvas;
  private readonly context: OffscreenCanvasRenderingContext2D;
  private failure: Error | null = null;
  frames = 0;

  static supported(): boolean {
    return typeof VideoEncoder !== 'undefined' && typeof OffscreenCanvas !== 'undefined';
  }

  constructor(private readonly source: HTMLCanvasElement, private readonly fps: number) {
    // VP8 wants even sizes: frames are copied into an even-sized canvas first
    const width = Math.max(2, source.width & ~1);
    const height = Math.max(2, source.height & ~1);
    this.frameCanvas = new OffscreenCanvas(width, height);
    this.context = this.frameCanvas.getContext('2d') as OffscreenCanvasRenderingContext2D;
    this.muxer = new Muxer({ target: new ArrayBufferTarget(), video: { codec: 'V_VP8', width, height, frameRate: fps } });
    this.encoder = new VideoEncoder({
      output: (chunk, meta) => this.muxer.addVideoChunk(chunk, meta),
      error: (e) => { this.failure = e instanceof Error ? e : new Error(String(e)); },
    });
    this.encoder.configure({ codec: 'vp8', width, height, bitrate: 4_000_000, framerate: fps });
  }

  /** Add what the source canvas shows now as the next frame. */
  async add(): Promise<void> {
    if (this.failure) throw this.failure;
    this.context.drawImage(this.source, 0, 0, this.frameCanvas.width, this.frameCanvas.height);
    const frame = new VideoFrame(this.frameCanvas, {
      timestamp: Math.round((this.frames * 1e6) / this.fps), duration: Math.round(1e6 / this.fps),
    });
    this.encoder.encode(frame, { keyFrame: this.frames % (2 * this.fps) === 0 });
    frame.close();
    this.frames++;
    // keep the encoder's queue short: frames are big, and SwiftShader renders faster than VP8 encodes
    while (this.encoder.encodeQueueSize > 4) await new Promise((resolve) => setTimeout(resolve, 5));
  }

  async finish(): Promise<Blob> {
    await this.encoder.flush();
    this.encoder.close();
    if (this.failure) throw this.failure;
    this.muxer.finalize();
    return new Blob([this.muxer.target.buffer], { type: 'video/webm' });
  }
}
