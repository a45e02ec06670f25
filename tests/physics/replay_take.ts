// Replays a recorded take through the page's own physics modules in node (bundled by esbuild), `runs`
// times, each in a fresh world, and prints one JSON line: per run the boxes knocked down and their final
// states. Run by tests/physics/test_replay.py and benchmarks/bench_physics.py:
//   node replay_take.mjs '{"mesh": "payload.json", "transforms": "take.transforms", "fps": 30, "preset": "tower", "runs": 2}'
import { readFileSync } from 'node:fs';
import { decodeMesh, type MeshPayloadJson } from '../../web/src/scene/MeshPayload';
import { loadRapier } from '../../web/src/physics/rapier';
import { SphereProxies } from '../../web/src/physics/SphereProxies';
import { TakeReplay, parseTakeTransforms } from '../../web/src/physics/TakeReplay';
import type { PresetName } from '../../web/src/physics/presets';

const config = JSON.parse(process.argv[2]) as {
  mesh: string; transforms: string; fps: number; preset: PresetName; runs: number; placement?: number[];
};
const R = await loadRapier();
const mesh = decodeMesh(JSON.parse(readFileSync(config.mesh, 'utf8')) as MeshPayloadJson);
const proxies = new SphereProxies(mesh.sphereRadius, mesh.positions, mesh.skinIndex, mesh.skinWeight, mesh.spheres);
const bytes = readFileSync(config.transforms);
const frames = parseTakeTransforms(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
const placement = config.placement ?? [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
const runs = [];
for (let i = 0; i < config.runs; i++) {
  const replay = new TakeReplay(R, [{ proxies, frames, placement }], config.fps, config.preset);
  const start = performance.now();
  const knockedDown = replay.run();
  const ms = performance.now() - start;
  runs.push({ knockedDown, boxes: replay.world.boxes.length, steps: replay.world.steps, balls: replay.world.balls.length,
    stepMs: ms / replay.world.steps, states: replay.world.boxStates(), spheres: proxies.count });
  replay.world.free();
}
console.log(JSON.stringify({ frames: frames.length, runs }));
