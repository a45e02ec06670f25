// The physics world of the studio (KinÊtre paper, "Physics-based Interactions"): the meshes' sphere proxies as
// kinematic position-based bodies (each step they are told where to be next, so Rapier gives them the
// velocity that gets them there and they hit boxes and balls with it), dynamic boxes and balls, and the
// ground. Fixed step 1/60 s and a seeded ball thrower: the same proxy positions give the same world, step for
// step.
import type { RigidBody } from '@dimforge/rapier3d-compat';
import {
  type BoxSpec, type Bounds, GRAVITY, type PresetName, nextThrow, seededRandom, sphereBounds, towerLayout,
} from './presets';
import type { Rapier } from './rapier';

export const STEP = 1 / 60; // seconds of simulated time per step
export const THROW_EVERY = 45; // steps between two dodgeballs (0.75 s)
export const MAX_BALLS = 24; // the oldest ball goes when a new one would exceed this
// A proxy asked to move faster than this (m/s) is teleported instead: a mesh swap, "fit" or a dragged
// placement must not fire boxes across the room.
export const MAX_PROXY_SPEED = 25;

/** A proxy radius in the world frame: one for every proxy, or one each (S; several meshes, each its own). */
export type Radii = number | Float64Array;

export const radiusOf = (radii: Radii, s: number): number => (typeof radii === 'number' ? radii : radii[s]);

export interface WorldSetup {
  preset: PresetName;
  centres: Float32Array; // S × 3 proxy centres at the start, world frame
  radius: Radii;
  seed?: number;
  boxes?: BoxSpec[]; // overrides the preset's boxes (the benchmark)
}

export class PhysicsWorld {
  readonly world: InstanceType<Rapier['World']>;
  readonly proxies: RigidBody[] = [];
  readonly boxes: { body: RigidBody; start: [number, number, number]; half: number }[] = [];
  readonly balls: { body: RigidBody; radius: number }[] = [];
  readonly bounds: Bounds;
  readonly preset: PresetName;
  steps = 0;
  private readonly radii: Float64Array; // per proxy, as its collider has it
  private readonly random: () => number;
  private readonly last: Float32Array;

  constructor(private readonly R: Rapier, setup: WorldSetup) {
    this.preset = setup.preset;
    this.random = seededRandom(setup.seed ?? 1);
    this.world = new R.World({ x: 0, y: -GRAVITY, z: 0 });
    this.world.timestep = STEP;
    this.world.createCollider(R.ColliderDesc.cuboid(50, 0.5, 50).setTranslation(0, -0.5, 0).setFriction(0.8));
    this.bounds = sphereBounds(setup.centres, setup.radius);
    this.last = Float32Array.from(setup.centres);
    this.radii = new Float64Array(setup.centres.length / 3);
    for (let s = 0; s < this.radii.length; s++) {
      this.radii[s] = radiusOf(setup.radius, s);
      const body = this.world.createRigidBody(R.RigidBodyDesc.kinematicPositionBased()
        .setTranslation(setup.centres[3 * s], setup.centres[3 * s + 1], setup.centres[3 * s + 2]));
      this.world.createCollider(R.ColliderDesc.ball(this.radii[s]).setFriction(0.6), body);
      this.proxies.push(body);
    }
    const boxes = setup.boxes ?? (setup.preset === 'tower' ? towerLayout(this.bounds) : []);
    for (const b of boxes) {
      const body = this.world.createRigidBody(R.RigidBodyDesc.dynamic().setTranslation(...b.position));
      this.world.createCollider(R.ColliderDesc.cuboid(b.half, b.half, b.half).setDensity(300).setFriction(0.7), body);
      this.boxes.push({ body, start: [...b.position], half: b.half });
    }
  }

  /** Where the proxies must be after the next step (S × 3, world frame), and their radii there (unchanged
   * when not given). */
  moveProxies(centres: Float32Array, radius: Radii = this.radii): void {
    let fastest = 0;
    for (let i = 0; i < centres.length; i++) fastest = Math.max(fastest, Math.abs(centres[i] - this.last[i]));
    const teleport = fastest > MAX_PROXY_SPEED * STEP;
    this.proxies.forEach((body, s) => {
      const t = { x: centres[3 * s], y: centres[3 * s + 1], z: centres[3 * s + 2] };
      if (teleport) body.setTranslation(t, true);
      else body.setNextKinematicTranslation(t);
    });
    this.last.set(centres.subarray(0, this.last.length));
    this.proxies.forEach((body, s) => {
      const r = radiusOf(radius, s);
      if (Math.abs(r - this.radii[s]) <= 1e-3 * this.radii[s]) return; // a placement scaled, not jitter
      this.radii[s] = r;
      body.collider(0).setRadius(r);
    });
  }

  /** One fixed step; in dodgeball, a ball is thrown every THROW_EVERY steps. */
  step(): void {
    if (this.preset === 'dodgeball' && this.steps % THROW_EVERY === 0) this.throwBall();
    this.world.step();
    this.steps++;
  }

  private throwBall(): void {
    const R = this.R;
    if (this.balls.length >= MAX_BALLS) this.world.removeRigidBody((this.balls.shift() as { body: RigidBody }).body);
    const t = nextThrow(this.bounds, this.random);
    const body = this.world.createRigidBody(R.RigidBodyDesc.dynamic().setTranslation(...t.position)
      .setLinvel(...t.velocity).setCcdEnabled(true).setAngularDamping(0.3));
    this.world.createCollider(R.ColliderDesc.ball(t.radius).setDensity(200).setRestitution(0.6), body);
    this.balls.push({ body, radius: t.radius });
  }

  /** Boxes whose centre has moved more than half an edge from where they started. */
  knockedDown(): number {
    return this.boxes.filter(({ body, start, half }) => {
      const p = body.translation();
      return Math.hypot(p.x - start[0], p.y - start[1], p.z - start[2]) > half;
    }).length;
  }

  /** Box centres and rotations, 7 floats each (x y z qx qy qz qw): what a test compares between runs. */
  boxStates(): number[] {
    return this.boxes.flatMap(({ body }) => {
      const p = body.translation();
      const q = body.rotation();
      return [p.x, p.y, p.z, q.x, q.y, q.z, q.w];
    });
  }

  free(): void {
    this.world.free();
  }
}
