// Physics play in the studio (KinÊtre paper, "Physics-based Interactions"): the sphere proxies of every mesh
// in the scene in one Rapier world with a scene preset (box tower, dodgeball, ground only), stepped at a fixed
// 1/60 s behind the render loop; reset by button, key X or the voice command "reset"; the proxies shown on
// request (key O); and the last recorded take (every mesh that moved) replayed through the physics
// deterministically into a WebM at the take's own frame rate.
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

/** One mesh of a replayed take: its id, frames and the placement it was recorded in. */
export interface ReplayedMesh { id: number; frames: number; placement: number[] }

export interface ReplayReport {
  frames: number; steps: number; knockedDown: number; boxes: number; videoBytes: number;
  preset: PresetName; meshes: ReplayedMesh[]; states: number[]; // what a node replay of the same take must match
}

/** One of the scene's meshes as shown. */
export interface ShownMesh {
  readonly id: number;
  readonly graph: SkinnedGraphMesh;
  /** Its world matrix (its placement as shown), column-major. */
  matrix(): ArrayLike<number>;
}

/** A take's mesh for the replay: its node transforms (URL) and the placement it was recorded in. */
export interface TakeMesh { id: number; transforms: string; placement: number[] }

/** What the playground needs from the page around it. */
export interface PlaygroundHost {
  readonly viewport: Viewport;
  /** The panel area its controls go in. */
  readonly area: HTMLElement;
  /** Every mesh shown, in the scene's order (all of them push boxes and balls). */
  meshes(): ShownMesh[];
  say(text: string, error?: boolean): void;
  progress(label: string | null, fraction?: number): void;
}

/** A mesh in the world: its proxies follow its newest node matrices through its placement. */
interface Body { mesh: ShownMesh; proxies: SphereProxies }

export class Playground {
  preset: PresetName | 'off';
  world: PhysicsWorld | null = null;
  replaying = false;
  lastReplay: ReplayReport | null = null;
  resets = 0; // worlds built so far (tests wait on it)
  private R: Rapier | null = null;
  private bodies: Body[] = []; // the meshes in the world, in the scene's order
  private readonly rows = new Map<number, Float32Array>(); // each mesh's newest node matrices, by id
  private readonly replayed = new Set<number>(); // the meshes a running replay poses
  private centres = new Float32Array(0);
  private radii = new Float64Array(0);
  private accumulator = 0;
  private take: { fps: number; meshes: TakeMesh[] } | null = null;
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
      <select id="physics-preset" title="physics scene: every mesh's spheres push boxes and balls"></select>
      <button id="physics-reset" title="X or say “reset”">Reset</button>
      <button id="physics-spheres" title="O: show the meshes' sphere proxies">Spheres</button>
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
  /** The newest node matrices of mesh `id`. */
  setTransforms(id: number, rows: Float32Array): void {
    this.rows.set(id, rows);
  }

  /** Whether a running replay poses mesh `id` (the page then leaves its live pose alone). */
  replays(id: number): boolean {
    return this.replayed.has(id);
  }

  /** A take recorded on the server: its meshes' node matrices (take-mesh<id>.transforms) and placements. */
  setTake(fps: number, meshes: TakeMesh[]): void {
    this.take = meshes.length ? { fps, meshes } : null;
    this.buttons.replay.disabled = !this.take;
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

  /** The meshes shown now as bodies, each mesh's proxies made once; true when they differ from the world's. */
  private follow(): boolean {
    const shown = this.host.meshes();
    const same = shown.length === this.bodies.length
      && shown.every((m, i) => m.id === this.bodies[i].mesh.id && m.graph === this.bodies[i].mesh.graph);
    if (same) {
      shown.forEach((m, i) => { this.bodies[i].mesh = m; });
      return false;
    }
    const before = new Map(this.bodies.map((b) => [b.mesh.graph, b.proxies]));
    this.bodies = shown.map((mesh) => {
      const d = mesh.graph.data;
      return { mesh, proxies: before.get(mesh.graph)
        ?? new SphereProxies(d.sphereRadius, d.positions, d.skinIndex, d.skinWeight, d.spheres) };
    });
    for (const id of this.rows.keys()) if (!shown.some((m) => m.id === id)) this.rows.delete(id);
    const count = this.bodies.reduce((n, b) => n + b.proxies.count, 0);
    this.centres = new Float32Array(3 * count);
    this.radii = new Float64Array(count);
    return true;
  }

  /** Every body's proxies where its mesh stands now (world frame) into `centres` and `radii`. */
  private place(): void {
    let s = 0;
    for (const { mesh, proxies } of this.bodies) {
      const matrix = mesh.matrix();
      proxies.centres(this.rows.get(mesh.id) ?? null, matrix, this.centres.subarray(3 * s));
      this.radii.fill(proxies.worldRadius(matrix), s, s + proxies.count);
      s += proxies.count;
    }
  }

  /** A fresh world of the current preset around the meshes where they stand now. */
  reset(): void {
    if (this.replaying) return;
    if (!this.R && this.preset !== 'off') { void this.rapier(); return; }
    this.follow();
    this.world?.free();
    this.world = null;
    this.accumulator = 0;
    if (this.R && this.bodies.length && this.preset !== 'off') {
      this.place();
      this.world = new PhysicsWorld(this.R, { preset: this.preset, centres: this.centres, radius: this.radii });
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
  private frame(dt: number): void {
    if (this.replaying) return;
    if (this.follow()) this.reset(); // a mesh came or went: a world around the meshes now shown
    const { world } = this;
    if (!world) return;
    this.accumulator += dt;
    let steps = 0;
    while (this.accumulator >= STEP && steps < MAX_STEPS_PER_FRAME) {
      this.place();
      world.moveProxies(this.centres, this.radii);
      world.step();
      this.accumulator -= STEP;
      steps++;
    }
    if (steps === MAX_STEPS_PER_FRAME) this.accumulator = 0;
    this.view.sync(world);
  }

  // --- takes --------------------------------------------------------------------------------------
  /** Replay the last take (every mesh of it still shown) through a fresh world (fixed step and seed) and
   * render it into a WebM. */
  async replay(): Promise<ReplayReport | null> {
    const { take } = this;
    if (!take || this.replaying) return null;
    this.follow();
    const parts = take.meshes.flatMap((m) => {
      const body = this.bodies.find((b) => b.mesh.id === m.id);
      return body ? [{ ...m, body }] : [];
    });
    if (!parts.length) {
      this.host.say('replay: the meshes of the take are no longer in the scene', true);
      return null;
    }
    const R = await this.rapier();
    const host = this.host;
    this.replaying = true;
    this.buttons.replay.disabled = true;
    for (const p of parts) this.replayed.add(p.id);
    let replay: TakeReplay | null = null;
    try {
      const tracks = await Promise.all(parts.map(async (p) => {
        const response = await fetch(p.transforms.replace(/^\//, ''));
        if (!response.ok) throw new Error(`cannot fetch the take of mesh ${p.id} (HTTP ${response.status})`);
        return { proxies: p.body.proxies, frames: parseTakeTransforms(await response.arrayBuffer()),
          placement: p.placement };
      }));
      const preset = this.preset === 'off' ? 'tower' : this.preset;
      replay = new TakeReplay(R, tracks, take.fps, preset);
      this.world?.free();
      this.world = replay.world;
      this.view.build(this.world);
      const video = TakeVideo.supported() ? new TakeVideo(host.viewport.renderer.domElement, take.fps) : null;
      const stepsPerFrame = Math.max(1, Math.round(1 / (STEP * take.fps)));
      for (let k = 0; ; k++) {
        tracks.forEach(({ frames }, i) => {
          const f = frames[Math.min(k, frames.length - 1)];
          parts[i].body.mesh.graph.setNodeMatrices(f.rows, f.seq);
        });
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
        frames: replay.frames, steps: replay.world.steps, knockedDown: replay.world.knockedDown(),
        boxes: replay.world.boxes.length, videoBytes: blob?.size ?? 0, preset,
        meshes: parts.map((p, i) => ({ id: p.id, frames: tracks[i].frames.length, placement: p.placement })),
        states: replay.world.boxStates(),
      };
      host.say(`replayed ${replay.frames} frames: ${this.lastReplay.knockedDown} of ${this.lastReplay.boxes} boxes down`
        + (blob ? '; the video is under “Physics WebM”' : '; this browser cannot encode video (no WebCodecs)'));
      return this.lastReplay;
    } catch (err) {
      host.say(`replay: ${(err as Error).message}`, true);
      return null;
    } finally {
      host.progress(null);
      this.replaying = false;
      this.replayed.clear();
      this.buttons.replay.disabled = !this.take;
      for (const { id, body } of parts) { // back to the live pose
        const rows = this.rows.get(id);
        if (rows) body.mesh.graph.setNodeMatrices(rows, body.mesh.graph.seq);
      }
      // the replay's world stays on screen until the next reset
    }
  }

  /** For the test hook: what the world holds now. */
  state() {
    const w = this.world;
    return {
      preset: this.preset,
      resets: this.resets,
      meshes: this.bodies.map((b) => b.mesh.id),
      spheres: this.bodies.reduce((n, b) => n + b.proxies.count, 0),
      radii: this.bodies.map((b) => b.proxies.radius), // each mesh's, mesh frame
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
