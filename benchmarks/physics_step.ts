// The physics step of the studio's world (web/src/physics/PhysicsWorld.ts) with S kinematic proxy spheres
// sweeping through B boxes: ms per world step (moveProxies + step), median and 90th percentile.
// Bundled by benchmarks/bench_physics.py twice: for node (ESM, prints a JSON line) and for Chromium (IIFE,
// sets window.physicsBench).
import { PhysicsWorld } from '../web/src/physics/PhysicsWorld';
import { boxGrid } from '../web/src/physics/presets';
import { loadRapier } from '../web/src/physics/rapier';

export interface BenchConfig { spheres: number; boxes: [number, number, number]; steps: number; warmup: number }

export async function physicsStep(config: BenchConfig) {
  const R = await loadRapier();
  const radius = 0.06;
  // a 1.6 m blob of spheres (a mesh's proxies) on a vertical disc, swept sideways through the box grid
  const rest = new Float32Array(3 * config.spheres);
  for (let s = 0; s < config.spheres; s++) {
    const a = s * 2.399963; // golden angle: an even disc
    const r = 0.5 * Math.sqrt((s + 0.5) / config.spheres);
    rest.set([r * Math.cos(a), 0.8 + 1.5 * r * Math.sin(a), 0.2 * Math.sin(3 * a)], 3 * s);
  }
  const [columns, rows, levels] = config.boxes;
  const world = new PhysicsWorld(R, {
    preset: 'ground', centres: rest.map((v, i) => (i % 3 === 0 ? v - 2 : v)), radius,
    boxes: boxGrid([0, 0, 0], 0.2, columns, rows, levels),
  });
  const centres = new Float32Array(rest.length);
  const times: number[] = [];
  // node only: CPU time of the whole timed loop, which a busy machine does not inflate as it does wall time
  const cpu = typeof process !== 'undefined' ? process.cpuUsage : null;
  let cpuStart = null as ReturnType<typeof process.cpuUsage> | null;
  for (let k = 0; k < config.warmup + config.steps; k++) {
    const x = -2 + 4 * (0.5 - 0.5 * Math.cos((2 * Math.PI * k) / 240)); // there and back in 4 s
    for (let i = 0; i < rest.length; i++) centres[i] = i % 3 === 0 ? rest[i] + x : rest[i];
    if (k === config.warmup && cpu) cpuStart = cpu();
    const t = performance.now();
    world.moveProxies(centres, radius);
    world.step();
    if (k >= config.warmup) times.push(performance.now() - t);
  }
  const used = cpu && cpuStart ? cpu(cpuStart) : null;
  const knockedDown = world.knockedDown();
  world.free();
  times.sort((a, b) => a - b);
  return {
    spheres: config.spheres, boxes: columns * rows * levels, steps: config.steps, knockedDown,
    ms_median: times[Math.floor(times.length / 2)], ms_p90: times[Math.floor(0.9 * times.length)],
    ms_mean: times.reduce((a, b) => a + b, 0) / times.length,
    ...(used ? { cpu_ms_mean: (used.user + used.system) / 1000 / config.steps } : {}),
  };
}

const config = (globalThis as { physicsBenchConfig?: BenchConfig }).physicsBenchConfig
  ?? (typeof process !== 'undefined' && process.argv[2] ? JSON.parse(process.argv[2]) as BenchConfig : null);
if (typeof window !== 'undefined') {
  (window as unknown as { physicsBench: Promise<unknown> }).physicsBench = physicsStep(config as BenchConfig);
} else if (config) {
  physicsStep(config).then((r) => console.log(JSON.stringify(r)));
}
