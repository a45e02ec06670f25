// A recorded take played back through the physics world, deterministically: a fresh world (fixed seed),
// the proxies carried by the take's own frames (node matrices at the take's rate, linearly interpolated
// to the fixed 1/60 s step), then a second of settling. The same take gives the same boxes every time.
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

export class TakeReplay {
  readonly world: PhysicsWorld;
  readonly totalSteps: number;
  readonly centres: Float32Array;
  private readonly a: Float32Array;
  private readonly b: Float32Array;
  private loaded = -1;
  private readonly radius: number;

  /** frames at `fps`; placement: the mesh → world matrix (column-major 4 × 4) of the take. */
  constructor(R: Rapier, readonly proxies: SphereProxies, readonly frames: TransformBlock[], readonly fps: number,
              readonly placement: ArrayLike<number>, preset: PresetName, seed = 1) {
    const n = 3 * proxies.count;
    this.centres = new Float32Array(n);
    this.a = new Float32Array(n);
    this.b = new Float32Array(n);
    this.radius = proxies.worldRadius(placement);
    proxies.centres(frames[0].rows, placement, this.centres);
    this.world = new PhysicsWorld(R, { preset, centres: this.centres, radius: this.radius, seed });
    this.totalSteps = Math.round(((frames.length - 1) / fps) / STEP) + SETTLE_STEPS;
  }

  get done(): boolean {
    return this.world.steps >= this.totalSteps;
  }

  /** Advance one fixed step; false once the replay is over. */
  next(): boolean {
    if (this.done) return false;
    const t = ((this.world.steps + 1) * STEP) * this.fps; // where the proxies must be after this step, in frames
    const i = Math.min(Math.floor(t), this.frames.length - 1);
    const j = Math.min(i + 1, this.frames.length - 1);
    if (this.loaded !== i) {
      this.proxies.centres(this.frames[i].rows, this.placement, this.a);
      this.proxies.centres(this.frames[j].rows, this.placement, this.b);
      this.loaded = i;
    }
    const f = j === i ? 0 : t - i;
    for (let k = 0; k < this.centres.length; k++) this.centres[k] = this.a[k] + f * (this.b[k] - this.a[k]);
    this.world.moveProxies(this.centres, this.radius);
    this.world.step();
    return true;
  }

  /** Run to the end (node, tests): the boxes knocked down. */
  run(): number {
    while (this.next());
    return this.world.knockedDown();
  }
}
