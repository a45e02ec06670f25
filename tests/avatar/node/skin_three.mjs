// Skin an animated glTF/GLB with three.js (the studio page's SkinnedMesh) in node, no WebGL needed:
// GLTFLoader builds the scene, an AnimationMixer poses it at each requested time, and
// SkinnedMesh.applyBoneTransform computes each vertex exactly as the page's vertex shader does.
// Usage: node skin_three.mjs FILE.glb TIME [TIME...]  -> JSON {frames: [[{mesh, primitive, positions}]]}
import { readFile } from "node:fs/promises";
import * as THREE from "../../../web/node_modules/three/build/three.module.js";
import { GLTFLoader } from "../../../web/node_modules/three/examples/jsm/loaders/GLTFLoader.js";

const [file, ...times] = process.argv.slice(2);
const gltf = await new GLTFLoader().parseAsync(withoutImages(await readFile(file)), "");
const scene = gltf.scene;
const mixer = new THREE.AnimationMixer(scene);
if (gltf.animations.length) mixer.clipAction(gltf.animations[0]).play();
const meshes = [];
scene.traverse((o) => { if (o.isSkinnedMesh) meshes.push(o); });
const frames = [];
const v = new THREE.Vector3();
for (const t of times.map(Number)) {
  mixer.setTime(t);
  scene.updateMatrixWorld(true);
  const frame = [];
  for (const mesh of meshes) {
    mesh.skeleton.update();
    const where = gltf.parser.associations.get(mesh) || {};
    const count = mesh.geometry.attributes.position.count;
    const out = new Float64Array(count * 3);
    for (let i = 0; i < count; i++) {
      mesh.getVertexPosition(i, v);              // bind position, then the bones (SkinnedMesh.applyBoneTransform)
      v.applyMatrix4(mesh.matrixWorld);
      out[3 * i] = v.x; out[3 * i + 1] = v.y; out[3 * i + 2] = v.z;
    }
    frame.push({ mesh: where.meshes, primitive: where.primitives, positions: Array.from(out) });
  }
  frames.push(frame);
}
process.stdout.write(JSON.stringify({ frames }));

// Images cannot be decoded without a DOM and do not move vertices: drop them from the GLB's JSON chunk.
function withoutImages(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const jsonLength = view.getUint32(12, true);
  const json = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
  delete json.textures; delete json.images; delete json.samplers;
  for (const m of json.materials || []) {
    for (const k of ["normalTexture", "occlusionTexture", "emissiveTexture"]) delete m[k];
    if (m.pbrMetallicRoughness) {
      delete m.pbrMetallicRoughness.baseColorTexture;
      delete m.pbrMetallicRoughness.metallicRoughnessTexture;
    }
    delete m.extensions;
  }
  let text = new TextEncoder().encode(JSON.stringify(json));
  const pad = (4 - (text.length % 4)) % 4;
  const rest = bytes.subarray(20 + jsonLength);                    // the BIN chunk, unchanged
  const out = new Uint8Array(12 + 8 + text.length + pad + rest.length);
  const o = new DataView(out.buffer);
  o.setUint32(0, 0x46546c67, true); o.setUint32(4, 2, true); o.setUint32(8, out.length, true);
  o.setUint32(12, text.length + pad, true); o.setUint32(16, 0x4e4f534a, true);
  out.set(text, 20); out.fill(0x20, 20 + text.length, 20 + text.length + pad);
  out.set(rest, 20 + text.length + pad);
  return out.buffer;
}
