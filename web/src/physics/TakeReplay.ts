// A recorded take played back through the physics world, deterministically: a fresh world (fixed seed),
// every mesh of the take with its proxies carried by its own frames (node matrices at the take's rate,
// linearly interpolated to the fixed 1/60 s step), then a second of settling. The same take gives the same boxes every time.
import { type TransformBlock, decodeTransforms } from '../net/protocol';
import { PhysicsWorld, STEP } from './PhysicsWorld';
import type { PresetName } from './presets';
import type { Rapier } from './rapier';
import type { SphereProxies } from './SphereProxies';

export const SETTLE_STEPS = 60; // after the last frame, so that falling boxes land before they are counted

/** A take's node matrices (take.transforms: one "KTX1" transform block per frame, concatenated). */
export function parseTakeTransforms(buffer: ArrayBuffer): TransformBlock[] {
  const frames: TransformBlock[] = [];
  const view = new DataView(buffer);
  for (let offset = 0; offset < buffer.byteLength;) {
    if (buffer.byteLength - offset < 32) throw new Error(`take transforms: ${buffer.byteLength - offset} stray bytes at the end`);
    const size = 32 + 48 * view.getUint32(offset + 12, true);
    const block = decodeTransforms(buffer.slice(offset, offset + size));
    if (!block) throw new Error(`take transforms: frame ${frames.length} is not a transform block`);
    frames.push(block);
    offset += size;
  }
  if (!frames.length) throw new Error('take transforms: the take has no frames');
  return frames;
}

/** One mesh of a take: its sphere proxies, its frames (node matrices) and where it stood (mesh → world,
 * column-major 4 × 4). */
export interface TakeTrack {
  proxies: SphereProxies;
  frames: TransformBlock[];
  placement: ArrayLike<number>;
}

export class TakeReplay {
  readonly world: PhysicsWorld;
  readonly totalSteps: number;
  readonly centres: Float32Array; // every track's proxies, in track order
  readonly frames: number; // the longest track's
  private readonly a: Float32Array;
  private readonly b: Float32Array;
  private readonly offsets: number[]; // where each track's proxies start in `centres`
  private readonly loaded: number[];
  private readonly radii: Float64Array;

  /** Every mesh of the take (its tracks) at `fps`; a track shorter than the others holds its last frame. */
  constructor(R: Rapier, readonly tracks: TakeTrack[], readonly fps: number, preset: PresetName, seed = 1) {
    this.offsets = [];
    let n = 0;
    for (const t of tracks) { this.offsets.push(n); n += 3 * t.proxies.count; }
    this.centres = new Float32Array(n);
    this.a = new Float32Array(n);
    this.b = new Float32Array(n);
    this.radii = new Float64Array(n / 3);
    this.loaded = tracks.map(() => -1);
    tracks.forEach((t, k) => {
      this.radii.fill(t.proxies.worldRadius(t.placement), this.offsets[k] / 3, this.offsets[k] / 3 + t.proxies.count);
      t.proxies.centres(t.frames[0].rows, t.placement, this.centres.subarray(this.offsets[k]));
    });
    this.frames = Math.max(...tracks.map((t) => t.frames.length));
    this.world = new PhysicsWorld(R, { preset, centres: this.centres, radius: this.radii, seed });
    this.totalSteps = Math.round(((this.frames - 1) / fps) / STEP) + SETTLE_STEPS;
  }

  get done(): boolean {
    return this.world.steps >= this.totalSteps;
  }

  /** Each track's frame index at the end of the next step and the fraction towards the one after. */
  private at(track: TakeTrack): [number, number, number] {
    const t = ((this.world.steps + 1) * STEP) * this.fps; // where the proxies must be after this step, in frames
    const last = track.frames.length - 1;
    const i = Math.min(Math.floor(t), last);
    const j = Math.min(i + 1, last);
    return [i, j, j === i ? 0 : t - i];
  }

  /** Advance one fixed step; false once the replay is over. */
  next(): boolean {
    if (this.done) return false;
    this.tracks.forEach((track, k) => {
      const [i, j, f] = this.at(track);
      const o = this.offsets[k], end = o + 3 * track.proxies.count;
      if (this.loaded[k] !== i) {
        track.proxies.centres(track.frames[i].rows, track.placement, this.a.subarray(o, end));
        track.proxies.centres(track.frames[j].rows, track.placement, this.b.subarray(o, end));
        this.loaded[k] = i;
      }
      for (let m = o; m < end; m++) this.centres[m] = this.a[m] + f * (this.b[m] - this.a[m]);
    });
    this.world.moveProxies(this.centres, this.radii);
    this.world.step();
    return true;
  }

  /** Run to the end (node, tests): the boxes knocked down. */
  run(): number {
    while (this.next());
    return this.world.knockedDown();
  }
}
