// Write a VRM Animation with three.js, not Kinetre: three-vrm's loader (VRMAnimationLoaderPlugin +
// createVRMAnimationClip) plays FILE.vrma on a VRM humanoid of other proportions, and three.js's GLTFExporter
// writes that humanoid's normalised bones and the clip bound to them as a new .vrma (a GLTFExporter plugin adds
// the VRMC_vrm_animation extension naming each bone's node, as the VRMA 1.0 specification asks).
// Usage: node vrma_rewrite_three.mjs FILE.vrma OUT.vrma
import { readFile, writeFile } from "node:fs/promises";
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { GLTFExporter } from "three/examples/jsm/exporters/GLTFExporter.js";
import { VRMHumanoid } from "@pixiv/three-vrm";
import { VRMAnimationLoaderPlugin, createVRMAnimationClip } from "@pixiv/three-vrm-animation";

// GLTFExporter reads its buffers through the browser's FileReader
globalThis.FileReader = class {
  readAsArrayBuffer(blob) { blob.arrayBuffer().then((b) => { this.result = b; this.onloadend?.(); }); }
  readAsDataURL(blob) {
    blob.arrayBuffer().then((b) => {
      this.result = `data:${blob.type || "application/octet-stream"};base64,${Buffer.from(b).toString("base64")}`;
      this.onloadend?.();
    });
  }
};

const [file, out] = process.argv.slice(2);
const bytes = await readFile(file);
const loader = new GLTFLoader();
loader.register((parser) => new VRMAnimationLoaderPlugin(parser));
const gltf = await loader.parseAsync(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), "");
const animation = gltf.userData.vrmAnimations[0];
const humanBones = gltf.parser.json.extensions.VRMC_vrm_animation.humanoid.humanBones;

// the receiving humanoid: the file's bones, each at 1.2x its offset from its parent, every rotation identity
const parents = {
  hips: null, spine: "hips", chest: "spine", neck: "chest", head: "neck",
  leftShoulder: "chest", leftUpperArm: "leftShoulder", leftLowerArm: "leftUpperArm", leftHand: "leftLowerArm",
  rightShoulder: "chest", rightUpperArm: "rightShoulder", rightLowerArm: "rightUpperArm", rightHand: "rightLowerArm",
  leftUpperLeg: "hips", leftLowerLeg: "leftUpperLeg", leftFoot: "leftLowerLeg", leftToes: "leftFoot",
  rightUpperLeg: "hips", rightLowerLeg: "rightUpperLeg", rightFoot: "rightLowerLeg", rightToes: "rightFoot",
};
const world = {};
gltf.scene.updateMatrixWorld(true);
for (const name of Object.keys(humanBones)) {
  const node = await gltf.parser.getDependency("node", humanBones[name].node);
  world[name] = node.getWorldPosition(new THREE.Vector3());
}
const present = (name) => (name == null || name in world ? name : present(parents[name]));
const scene = new THREE.Scene();
const raw = {};
for (const name of Object.keys(parents)) {
  if (!(name in world)) continue;
  const up = present(parents[name]);
  const bone = new THREE.Bone();
  bone.name = `raw_${name}`;
  bone.position.copy(up ? world[name].clone().sub(world[up]).multiplyScalar(1.2) : world[name]);
  (up ? raw[up] : scene).add(bone);
  raw[name] = bone;
}
scene.updateMatrixWorld(true);
const humanoid = new VRMHumanoid(Object.fromEntries(Object.entries(raw).map(([k, node]) => [k, { node }])));
const root = humanoid.normalizedHumanBonesRoot;
const vrm = { humanoid, expressionManager: null, lookAt: null, meta: { metaVersion: "1" }, scene };
const clip = createVRMAnimationClip(animation, vrm);

class VrmAnimationExtension {
  constructor(writer) { this.writer = writer; this.name = "VRMC_vrm_animation"; }
  afterParse() {
    const bones = {};
    for (const name of Object.keys(raw)) {
      const node = humanoid.getNormalizedBoneNode(name);
      if (this.writer.nodeMap.has(node)) bones[name] = { node: this.writer.nodeMap.get(node) };
    }
    const json = this.writer.json;
    json.extensions = { ...(json.extensions || {}), VRMC_vrm_animation: { specVersion: "1.0", humanoid: { humanBones: bones } } };
    this.writer.extensionsUsed[this.name] = true;
  }
}
const exporter = new GLTFExporter();
exporter.register((writer) => new VrmAnimationExtension(writer));
const glb = await exporter.parseAsync(root, { binary: true, animations: [clip] });
await writeFile(out, Buffer.from(glb));
