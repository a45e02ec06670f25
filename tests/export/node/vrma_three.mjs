// Play a .vrma with three-vrm in node, no WebGL needed: GLTFLoader + VRMAnimationLoaderPlugin read it,
// createVRMAnimationClip binds it to a VRM humanoid built here (a T-posed rig of the file's bones with other
// proportions, and one VRMExpression per expression in the file), an AnimationMixer plays it.
// Usage: node vrma_three.mjs FILE.vrma TIME [TIME...]
//   -> JSON {bones, frames, duration, restHips, presets, custom,
//            poses: [{directions: {bone: [x,y,z]}, hips: [x,y,z], weights: {expression: w}}]}
// `directions` are each bone's world +X/-X/-Y/+Y T-pose direction as posed (the way the bone points).
import { readFile } from "node:fs/promises";
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { VRMExpression, VRMExpressionManager, VRMHumanoid } from "@pixiv/three-vrm";
import { VRMAnimationLoaderPlugin, createVRMAnimationClip } from "@pixiv/three-vrm-animation";

const [file, ...times] = process.argv.slice(2);
const bytes = await readFile(file);
const loader = new GLTFLoader();
loader.register((parser) => new VRMAnimationLoaderPlugin(parser));
const gltf = await loader.parseAsync(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), "");
const animation = gltf.userData.vrmAnimations[0];

// the receiving humanoid: the file's bones at 1.3x its T-pose offsets, every rotation identity
const parents = {
  hips: null, spine: "hips", neck: "spine", head: "neck",
  leftUpperArm: "spine", leftLowerArm: "leftUpperArm", leftHand: "leftLowerArm",
  rightUpperArm: "spine", rightLowerArm: "rightUpperArm", rightHand: "rightLowerArm",
  leftUpperLeg: "hips", leftLowerLeg: "leftUpperLeg", leftFoot: "leftLowerLeg", leftToes: "leftFoot",
  rightUpperLeg: "hips", rightLowerLeg: "rightUpperLeg", rightFoot: "rightLowerLeg", rightToes: "rightFoot",
};
const pointing = (name) => (name.startsWith("left") && /Arm|Hand/.test(name) ? [1, 0, 0]
  : name.startsWith("right") && /Arm|Hand/.test(name) ? [-1, 0, 0]
  : /Leg/.test(name) ? [0, -1, 0] : [0, 1, 0]);
const json = gltf.parser.json;
const humanBones = json.extensions.VRMC_vrm_animation.humanoid.humanBones;
const scene = new THREE.Scene();
const raw = {};
for (const name of Object.keys(parents)) {
  if (!(name in humanBones)) continue;
  const bone = new THREE.Bone();
  bone.name = `raw_${name}`;
  bone.position.fromArray(json.nodes[humanBones[name].node].translation).multiplyScalar(1.3);
  (parents[name] ? raw[parents[name]] : scene).add(bone);
  raw[name] = bone;
}
scene.updateMatrixWorld(true);
const humanoid = new VRMHumanoid(Object.fromEntries(Object.entries(raw).map(([k, node]) => [k, { node }])));
scene.add(humanoid.normalizedHumanBonesRoot);
const expressionManager = new VRMExpressionManager();
const names = [...animation.expressionTracks.preset.keys(), ...animation.expressionTracks.custom.keys()];
for (const name of names) {
  const expression = new VRMExpression(name);
  scene.add(expression);
  expressionManager.registerExpression(expression);
}
const vrm = { humanoid, expressionManager, lookAt: null, meta: { metaVersion: "1" }, scene };
const clip = createVRMAnimationClip(animation, vrm);
const mixer = new THREE.AnimationMixer(scene);
const action = mixer.clipAction(clip);
action.setLoop(THREE.LoopOnce, 1);      // the last key is the last frame, not the first one again
action.clampWhenFinished = true;
action.play();

const poses = [];
const q = new THREE.Quaternion();
const p = new THREE.Vector3();
for (const t of times.map(Number)) {
  mixer.setTime(t);
  humanoid.update();
  scene.updateMatrixWorld(true);
  const directions = {};
  for (const [name, bone] of Object.entries(raw)) {
    bone.getWorldQuaternion(q);
    directions[name] = new THREE.Vector3(...pointing(name)).applyQuaternion(q).toArray();
  }
  raw.hips.getWorldPosition(p);
  const weights = Object.fromEntries(names.map((n) => [n, expressionManager.getExpression(n).weight]));
  poses.push({ directions, hips: p.toArray(), weights });
}
const first = animation.humanoidTracks.rotation.values().next().value;
process.stdout.write(JSON.stringify({
  bones: [...animation.humanoidTracks.rotation.keys()],
  translated: [...animation.humanoidTracks.translation.keys()],
  frames: first.times.length,
  duration: animation.duration,
  restHips: animation.restHipsPosition.toArray(),
  presets: [...animation.expressionTracks.preset.keys()],
  custom: [...animation.expressionTracks.custom.keys()],
  poses,
}));
