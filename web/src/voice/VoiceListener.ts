// Voice commands, offline: the microphone is captured in an AudioWorklet, cut into utterances by an
// energy threshold, downsampled to 16 kHz mono and posted as WAV to the server, which recognises
// "possess", "release" and the subsets with pocketsphinx and applies them (the KinÊtre paper's speech interface).
import { encodeWav, resample } from './wav';

// The worklet only forwards 128-sample blocks; cutting and encoding happen on the main thread.
const WORKLET = `
class KinetreCapture extends AudioWorkletProcessor {
  process(inputs) {
    const ch = inputs[0] && inputs[0][0];
    if (ch) this.port.postMessage(ch.slice(0));
    return true;
  }
}
registerProcessor('kinetre-capture', KinetreCapture);
`;

export interface VoiceResult {
  command: { verb: string | null; subset: string | null; text: string } | null;
  error?: string;
}

export class VoiceListener {
  private context: AudioContext | null = null;
  private stream: MediaStream | null = null;
  private utterance: Float32Array[] = [];
  private speaking = false;
  private silentBlocks = 0;
  private noise = 0.003;
  level = 0;
  utterances = 0;

  /** `who`: the voice request's query string (the client, and the mesh its "possess" takes). */
  constructor(private readonly who: () => string, private readonly onResult: (r: VoiceResult) => void,
              private readonly threshold = 4.0) {}

  get listening(): boolean {
    return this.context !== null;
  }

  async start(): Promise<void> {
    if (this.context) return;
    this.stream = await navigator.mediaDevices.getUserMedia({ audio: { channelCount: 1, echoCancellation: true } });
    const context = new AudioContext();
    const url = URL.createObjectURL(new Blob([WORKLET], { type: 'text/javascript' }));
    await context.audioWorklet.addModule(url);
    const node = new AudioWorkletNode(context, 'kinetre-capture');
    node.port.onmessage = (e: MessageEvent<Float32Array>) => this.block(e.data, context.sampleRate);
    context.createMediaStreamSource(this.stream).connect(node);
    this.context = context;
  }

  stop(): void {
    this.stream?.getTracks().forEach((t) => t.stop());
    void this.context?.close();
    this.context = null;
    this.stream = null;
  }

  /** Energy-based endpointing: speech starts above threshold × noise floor, ends after 0.4 s of quiet. */
  private block(samples: Float32Array, rate: number): void {
    let sum = 0;
    for (const s of samples) sum += s * s;
    const rms = Math.sqrt(sum / samples.length);
    this.level = rms;
    const loud = rms > this.threshold * this.noise;
    if (!this.speaking) {
      this.noise = Math.max(1e-4, 0.995 * this.noise + 0.005 * rms);
      this.utterance = [...this.utterance.slice(-24), samples]; // keep ~70 ms before the onset
      if (loud) { this.speaking = true; this.silentBlocks = 0; }
      return;
    }
    this.utterance.push(samples);
    this.silentBlocks = loud ? 0 : this.silentBlocks + 1;
    const seconds = (this.utterance.length * samples.length) / rate;
    if ((this.silentBlocks * samples.length) / rate > 0.4 || seconds > 4) {
      const all = new Float32Array(this.utterance.reduce((n, b) => n + b.length, 0));
      let offset = 0;
      for (const b of this.utterance) { all.set(b, offset); offset += b.length; }
      this.utterance = [];
      this.speaking = false;
      if (seconds > 0.3) void this.send(resample(all, rate, 16000));
    }
  }

  async send(pcm16k: Float32Array): Promise<void> {
    this.utterances++;
    const response = await fetch(`api/voice?${this.who()}`, {
      method: 'POST', body: encodeWav(pcm16k, 16000), headers: { 'Content-Type': 'audio/wav' },
    });
    const body = (await response.json()) as VoiceResult & { error?: string };
    this.onResult(response.ok ? body : { command: null, error: body.error ?? `HTTP ${response.status}` });
  }
}
