// The scene presets (paper Fig. 8): a tower of boxes beside the mesh, balls thrown at it (dodgeball), or the
// ground alone. Layouts are placed relative to the proxies' bounds at reset, so they suit any mesh size.

export type PresetName = 'tower' | 'dodgeball' | 'ground';
export const PRESETS: PresetName[] = ['tower', 'dodgeball', 'ground'];
export type Vec3 = [number, number, number];

export interface Bounds { min: Vec3; max: Vec3 }

export interface BoxSpec { position: Vec3; half: number }

export interface Throw { position: Vec3; velocity: Vec3; radius: number }

export const GRAVITY = 9.81;
const TOWER = { columns: 2, rows: 2, levels: 5 };
const THROW_SPEED = 7; // m/s towards a random point of the mesh
const THROW_DISTANCE = 3.5; // m in front of the mesh (towards the default camera, +z)

/** Bounds of the proxies' centres, grown by their radius (one for all, or one per proxy). */
export function sphereBounds(centres: Float32Array, radius: number | Float64Array): Bounds {
  const min: Vec3 = [Infinity, Infinity, Infinity];
  const max: Vec3 = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < centres.length; i += 3) {
    const r = typeof radius === 'number' ? radius : radius[i / 3];
    for (let k = 0; k < 3; k++) {
      min[k] = Math.min(min[k], centres[i + k] - r);
      max[k] = Math.max(max[k], centres[i + k] + r);
    }
  }
  if (!Number.isFinite(min[0])) return { min: [-0.5, 0, -0.5], max: [0.5, 1, 0.5] }; // no proxies
  return { min, max };
}

/** Box edge for a mesh of this height: a tower of 5 is about as tall as the mesh, within 8–30 cm. */
export function boxEdge(bounds: Bounds): number {
  return Math.min(0.3, Math.max(0.08, (bounds.max[1] - Math.max(0, bounds.min[1])) / TOWER.levels));
}

/** A 2 × 2 tower, 5 boxes high, standing on the ground just right of the mesh (+x), level with its middle. */
export function towerLayout(bounds: Bounds): BoxSpec[] {
  const edge = boxEdge(bounds);
  const half = edge / 2;
  const x0 = bounds.max[0] + 0.5 * edge; // a half-box gap: a sideways swing reaches it
  const z0 = (bounds.min[2] + bounds.max[2]) / 2 - half;
  const boxes: BoxSpec[] = [];
  for (let level = 0; level < TOWER.levels; level++) {
    for (let c = 0; c < TOWER.columns; c++) {
      for (let r = 0; r < TOWER.rows; r++) {
        boxes.push({ position: [x0 + c * edge + half, half + level * edge, z0 + r * edge], half: half * 0.995 });
      }
    }
  }
  return boxes;
}

/** A grid of boxes (for the benchmark): columns × rows × levels, centred on `centre`, standing on y = 0. */
export function boxGrid(centre: Vec3, edge: number, columns: number, rows: number, levels: number): BoxSpec[] {
  const boxes: BoxSpec[] = [];
  for (let level = 0; level < levels; level++) {
    for (let c = 0; c < columns; c++) {
      for (let r = 0; r < rows; r++) {
        boxes.push({
          position: [centre[0] + (c - (columns - 1) / 2) * edge, edge / 2 + level * edge, centre[2] + (r - (rows - 1) / 2) * edge],
          half: edge * 0.495,
        });
      }
    }
  }
  return boxes;
}

/** mulberry32: a small seeded generator, so every replay throws the same balls. */
export function seededRandom(seed: number): () => number {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/** The next dodgeball: from in front of the mesh, aimed (ballistically) at a random point of its bounds. */
export function nextThrow(bounds: Bounds, random: () => number): Throw {
  const size = Math.max(bounds.max[1] - bounds.min[1], 0.3);
  const radius = Math.min(0.15, Math.max(0.05, size / 14));
  const cx = (bounds.min[0] + bounds.max[0]) / 2;
  const position: Vec3 = [cx + (random() - 0.5) * size, Math.max(radius, bounds.min[1]) + (0.5 + 0.3 * random()) * size,
    bounds.max[2] + THROW_DISTANCE];
  const target: Vec3 = [0, 1, 2].map((k) => bounds.min[k] + (0.2 + 0.6 * random()) * (bounds.max[k] - bounds.min[k])) as Vec3;
  const d: Vec3 = [target[0] - position[0], target[1] - position[1], target[2] - position[2]];
  const time = Math.hypot(...d) / THROW_SPEED;
  return { position, radius, velocity: [d[0] / time, d[1] / time + (GRAVITY * time) / 2, d[2] / time] };
}
