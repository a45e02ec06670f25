// Physics play in the studio (KinÊtre paper, "Physics-based Interactions"): the possessed mesh's sphere
// proxies in a Rapier world with a scene preset (box tower, dodgeball, ground only), stepped at a fixed
// 1/60 s behind the render loop; reset by button, key X or the voice command "reset"; the proxies shown on request
// (key O); and the last recorded take replayed through the physics deterministically into a WebM at the
// take's own frame rate.
import type { MeshData } from '../scene/MeshPayload';
import type { SkinnedGraphMesh } from '../scene/SkinnedGraphMesh';
import type { Viewport } from '../scene/Viewport';
import { PhysicsView } from './PhysicsView';
import { PhysicsWorld, STEP } from './PhysicsWorld';
import { PRESETS, type PresetName } from './presets';
import { type Rapier, loadRapier } from './rapier';
import { SphereProxies } from './SphereProxies';
import { TakeReplay, parseTakeTransforms } from './TakeReplay';
import { TakeVideo } from './TakeVideo';

const LABELS: Record<PresetName | 'off', string> = {
  off: 'no physics', tower: 'box tower', dodgeball: 'dodgeball', ground: 'ground only',
};
const MAX_STEPS_PER_FRAME = 4; // a slow frame drops simulated time rather than spiralling

export interface ReplayReport {
  frames: number; steps: number; knockedDown: number; boxes: number; videoBytes: number;
  preset: PresetName; placement: number[]; states: number[]; // what a node replay of the same take must match
}

/** What the playground needs from the page around it. */
export interface PlaygroundHost {
  readonly viewport: Viewport;
  /** The panel area its controls go in. */
  readonly area: HTMLElement;
  /** The live mesh's world matrix (its placement), column-major. */
  meshMatrix(): ArrayLike<number>;
  /** The live mesh, which a replay poses; null before one is loaded. */
  liveMesh(): SkinnedGraphMesh | null;
  say(text: string, error?: boolean): void;
  progress(label: string | null, fraction?: number): void;
}

export class Playground {
  preset: PresetName | 'off';
  world: PhysicsWorld | null = null;
  proxies: SphereProxies | null = null;
  replaying = false;
  lastReplay: ReplayReport | null = null;
  resets = 0; // worlds built so far (tests wait on it)
  private R: Rapier | null = null;
  private rows: Float32Array | null = null;
  private centres = new Float32Array(0);
  private accumulator = 0;
  private take: { url: string; fps: number; placement: number[] } | null = null;
  private readonly view: PhysicsView;
  private readonly select: HTMLSelectElement;
  private readonly buttons: Record<'reset' | 'spheres' | 'replay', HTMLButtonElement>;
  private readonly link: HTMLAnchorElement;

  constructor(private readonly host: PlaygroundHost) {
    this.view = new PhysicsView(host.viewport.scene);
    const wanted = new URLSearchParams(location.search).get('physics');
    this.preset = PRESETS.includes(wanted as PresetName) ? (wanted as PresetName) : 'off';
    const row = document.createElement('div');
    row.className = 'row';
    row.id = 'physics';
    row.innerHTML = `
      <select id="physics-preset" title="physics scene: the mesh's spheres push boxes and balls"></select>
      <button id="physics-reset" title="X or say “reset”">Reset</button>
      <button id="physics-spheres" title="O: show the mesh's sphere proxies">Spheres</button>
      <button id="physics-replay" title="replay the last take through the physics into a WebM" disabled>Replay take</button>
      <a id="physics-video" class="download" hidden>Physics WebM</a>`;
    host.area.appendChild(row);
    this.select = row.querySelector('select') as HTMLSelectElement;
    for (const name of ['off', ...PRESETS] as const) this.select.add(new Option(LABELS[name], name));
    this.select.value = this.preset;
    this.select.addEventListener('change', () => {
      this.setPreset(this.select.value as PresetName | 'off');
      this.select.blur(); // give the keyboard shortcuts back
    });
    const button = (id: string) => row.querySelector(`#physics-${id}`) as HTMLButtonElement;
    this.buttons = { reset: button('reset'), spheres: button('spheres'), replay: button('replay') };
    this.buttons.reset.addEventListener('click', () => this.reset());
    this.buttons.spheres.addEventListener('click', () => this.toggleSpheres());
    this.buttons.replay.addEventListener('click', () => void this.replay());
    this.link = row.querySelector('#physics-video') as HTMLAnchorElement;
    this.showControls();
    window.addEventListener('keydown', (e) => {
      if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement || e.repeat) return;
      const key = e.key.toLowerCase();
      if (key === 'x') this.reset();
      else if (key === 'o') this.toggleSpheres();
      else return;
      e.preventDefault();
    });
    host.viewport.onFrame((dt) => this.frame(dt));
    if (this.preset !== 'off') void this.rapier();
  }

  // --- from the studio ----------------------------------------------------------------------------
  setMesh(data: MeshData): void {
    this.proxies = new SphereProxies(data.sphereRadius, data.positions, data.skinIndex, data.skinWeight, data.spheres);
    this.centres = new Float32Array(3 * this.proxies.count);
    this.rows = null;
    this.take = null;
    this.buttons.replay.disabled = true;
    this.showControls();
    this.reset();
  }

  /** The newest node matrices of the live mesh. */
  setTransforms(rows: Float32Array): void {
    this.rows = rows;
  }

  /** A take recorded on the server: its node matrices (take.transforms) and the placement it was shown in. */
  setTake(url: string, fps: number, placement: number[]): void {
    this.take = { url, fps, placement };
    this.buttons.replay.disabled = false;
    this.showControls();
  }

  setPreset(preset: PresetName | 'off'): void {
    this.preset = preset;
    this.select.value = preset;
    this.showControls();
    this.reset();
  }

  /** Only the controls in use: a world's (reset, spheres) while a preset is on, the replay once there is a take. */
  private showControls(): void {
    this.buttons.reset.hidden = this.preset === 'off';
    this.buttons.spheres.hidden = this.preset === 'off';
    this.buttons.replay.hidden = !this.take;
  }

  /** Rapier, loaded on first use (then a reset builds the world). */
  private async rapier(): Promise<Rapier> {
    if (!this.R) {
      this.R = await loadRapier();
      this.reset();
    }
    return this.R;
  }

  /** A fresh world of the current preset around the mesh where it stands now. */
  reset(): void {
    if (this.replaying) return;
    if (!this.R && this.preset !== 'off') { void this.rapier(); return; }
    this.world?.free();
    this.world = null;
    this.accumulator = 0;
    if (this.R && this.proxies && this.preset !== 'off') {
      const placement = this.placement();
      this.world = new PhysicsWorld(this.R, {
        preset: this.preset, centres: this.proxies.centres(this.rows, placement, this.centres),
        radius: this.proxies.worldRadius(placement),
      });
      this.resets++;
    }
    this.view.build(this.world);
  }

  toggleSpheres(): void {
    this.view.showSpheres = !this.view.showSpheres;
    this.buttons.spheres.classList.toggle('active', this.view.showSpheres);
    if (this.world) this.view.sync(this.world);
  }

  // --- live stepping ------------------------------------------------------------------------------
  private placement(): ArrayLike<number> {
    return this.host.meshMatrix();
  }

  private frame(dt: number): void {
    const { world, proxies } = this;
    if (!world || !proxies || this.replaying) return;
    this.accumulator += dt;
    let steps = 0;
    while (this.accumulator >= STEP && steps < MAX_STEPS_PER_FRAME) {
      const placement = this.placement();
      world.moveProxies(proxies.centres(this.rows, placement, this.centres), proxies.worldRadius(placement));
      world.step();
      this.accumulator -= STEP;
      steps++;
    }
    if (steps === MAX_STEPS_PER_FRAME) this.accumulator = 0;
    this.view.sync(world);
  }

  // --- takes --------------------------------------------------------------------------------------
  /** Replay the last take through a fresh world (fixed step and seed) and render it into a WebM. */
  async replay(): Promise<ReplayReport | null> {
    const { take, proxies } = this;
    const mesh = this.host.liveMesh();
    if (!take || !proxies || !mesh || this.replaying) return null;
    const R = await this.rapier();
    const host = this.host;
    this.replaying = true;
    this.buttons.replay.disabled = true;
    let replay: TakeReplay | null = null;
    try {
      const response = await fetch(take.url.replace(/^\//, ''));
      if (!response.ok) throw new Error(`cannot fetch the take (HTTP ${response.status})`);
      const frames = parseTakeTransforms(await response.arrayBuffer());
      const preset = this.preset === 'off' ? 'tower' : this.preset;
      replay = new TakeReplay(R, proxies, frames, take.fps, take.placement, preset);
      this.world?.free();
      this.world = replay.world;
      this.view.build(this.world);
      const video = TakeVideo.supported() ? new TakeVideo(host.viewport.renderer.domElement, take.fps) : null;
      const stepsPerFrame = Math.max(1, Math.round(1 / (STEP * take.fps)));
      for (let k = 0; ; k++) {
        const f = frames[Math.min(k, frames.length - 1)];
        mesh.setNodeMatrices(f.rows, f.seq);
        this.view.sync(replay.world);
        host.viewport.renderer.render(host.viewport.scene, host.viewport.camera);
        await video?.add();
        if (k % 10 === 0) host.progress('replaying the take', replay.world.steps / replay.totalSteps);
        if (replay.done) break;
        for (let s = 0; s < stepsPerFrame; s++) replay.next();
      }
      const blob = video ? await video.finish() : null;
      if (blob) {
        if (this.link.href) URL.revokeObjectURL(this.link.href);
        this.link.href = URL.createObjectURL(blob);
        this.link.download = `kinetre-physics-${preset}.webm`;
        this.link.hidden = false;
      }
      this.lastReplay = {
        frames: frames.length, steps: replay.world.steps, knockedDown: replay.world.knockedDown(),
        boxes: replay.world.boxes.length, videoBytes: blob?.size ?? 0,
        preset, placement: take.placement, states: replay.world.boxStates(),
      };
      host.say(`replayed ${frames.length} frames: ${this.lastReplay.knockedDown} of ${this.lastReplay.boxes} boxes down`
        + (blob ? '; the video is under “Physics WebM”' : '; this browser cannot encode video (no WebCodecs)'));
      return this.lastReplay;
    } catch (err) {
      host.say(`replay: ${(err as Error).message}`, true);
      return null;
    } finally {
      host.progress(null);
      this.replaying = false;
      this.buttons.replay.disabled = !this.take;
      if (this.rows) mesh.setNodeMatrices(this.rows, mesh.seq); // back to the live pose
      // the replay's world stays on screen until the next reset
    }
  }

  /** For the test hook: what the world holds now. */
  state() {
    const w = this.world;
    return {
      preset: this.preset,
      resets: this.resets,
      spheres: this.proxies?.count ?? 0,
      radius: this.proxies?.radius ?? 0,
      showSpheres: this.view.showSpheres,
      steps: w?.steps ?? 0,
      boxes: w ? w.boxes.map(({ body }) => { const p = body.translation(); return [p.x, p.y, p.z]; }) : [],
      knockedDown: w?.knockedDown() ?? 0,
      balls: w?.balls.length ?? 0,
      proxies: w ? w.proxies.slice(0, 8).map((b) => { const p = b.translation(); return [p.x, p.y, p.z]; }) : [],
      replaying: this.replaying,
      lastReplay: this.lastReplay,
    };
  }
}
