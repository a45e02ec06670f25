// Run the page's hand and face drive (web/src/avatar/Fingers.ts and Expressions.ts, bundled by esbuild into
// DIR) on a fixture from stdin: {plan, joints, nodes, map, positions, tracked, hands (T x 2 x (21 x 3 | null)),
// faces (T x {name: weight} | null)} and the avatar FILE.glb. Per frame the body is retargeted
// (retarget.ts), the fingers follow the hands, the local matrices are set on the bones GLTFLoader built
// and the face's weights on its meshes; prints {world, local, bones (three.js world positions per joint),
// morphs (per frame, per mesh index, morphTargetInfluences), how} as JSON.
// Usage: node hands_face_ts.mjs DIR FILE.glb < fixture.json
import { readFileSync } from "node:fs";
import { readFile } from "node:fs/promises";
import { pathToFileURL } from "node:url";
import * as THREE from "../../../web/node_modules/three/build/three.module.js";
import { GLTFLoader } from "../../../web/node_modules/three/examples/jsm/loaders/GLTFLoader.js";

const [dir, file] = process.argv.slice(2);
const load = (name) => import(pathToFileURL(`${dir}/${name}.js`).href);
const { Retargeter } = await load("retarget");
const { FingerRetargeter, fingerChains } = await load("Fingers");
const { mapExpressions, expressionWeights, applyExpressions } = await load("Expressions");
const fixture = JSON.parse(readFileSync(0, "utf8"));
const bytes = await readFile(file);
const gltf = await new GLTFLoader().parseAsync(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), "");
const bones = await Promise.all(fixture.nodes.map((n) => gltf.parser.getDependency("node", n)));
const meshes = new Map();
gltf.scene.traverse((o) => {
  const m = gltf.parser.associations.get(o)?.meshes;
  if (m !== undefined && o.morphTargetInfluences) meshes.set(m, [...(meshes.get(m) ?? []), o]);
});
const plan = fixture.plan;
const body = new Retargeter(plan);
const chains = fingerChains(fixture.joints, plan.real_parents, {}, fixture.map);
const fingers = new FingerRetargeter(plan, chains, () => null);
const expressions = mapExpressions(gltf.parser.json);
const out = { world: [], local: [], bones: [], morphs: [], how: expressions.how, chains };
const m = new THREE.Matrix4();
const v = new THREE.Vector3();
fixture.positions.forEach((p, t) => {
  const frame = fingers.frame(body.frame(p, fixture.tracked[t]), fixture.hands[t]);
  out.world.push(frame.world);
  out.local.push(frame.local);
  frame.local.forEach((l, j) => {
    m.set(...l[0], ...l[1], ...l[2], 0, 0, 0, 1);
    m.decompose(bones[j].position, bones[j].quaternion, bones[j].scale);
  });
  gltf.scene.updateMatrixWorld(true);
  out.bones.push(bones.map((b) => b.getWorldPosition(v).toArray()));
  if (fixture.faces[t]) applyExpressions(expressionWeights(expressions, fixture.faces[t]), meshes);
  out.morphs.push(Object.fromEntries([...meshes].map(([k, list]) => [k, [...list[0].morphTargetInfluences]])));
});
process.stdout.write(JSON.stringify(out));
