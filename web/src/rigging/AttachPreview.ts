// What "possess" would attach right now (KinÊtre paper, "Constraints"; shown live before possession): joints
// within 10 cm of a graph node, and the graph nodes within 10 cm of a joint or a bone. Computed in the mesh's
// own frame, where the server attaches (so a scaled-up mesh reaches further, exactly as on the server).
import * as THREE from 'three';
import { KINECT20_BONES } from '../capture/kinect20';
import type { Vec3 } from '../net/protocol';

const REACH = 0.1;
const BONE_STEPS = 8;
const IDLE = new THREE.Color(0x4a90d9);
const HOT = new THREE.Color(0xff8a00);

export class AttachPreview {
  readonly points: THREE.Points;
  private readonly nodes: Float32Array;
  private readonly colours: Float32Array;
  attachableJoints: boolean[] = [];
  hotNodes = 0;

  constructor(nodes: Float32Array) {
    this.nodes = nodes;
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(nodes, 3));
    this.colours = new Float32Array(nodes.length);
    geometry.setAttribute('color', new THREE.BufferAttribute(this.colours, 3));
    this.points = new THREE.Points(geometry, new THREE.PointsMaterial({
      size: 0.035, vertexColors: true, depthTest: false, transparent: true, opacity: 0.9,
    }));
    this.points.renderOrder = 8;
    this.points.frustumCulled = false;
  }

  /** `skeletons` in world space; `meshWorld` is the mesh's local → world matrix. */
  update(skeletons: (Vec3 | null)[][], meshWorld: THREE.Matrix4): boolean[][] {
    const toLocal = meshWorld.clone().invert();
    const n = this.nodes.length / 3;
    const hot = new Uint8Array(n);
    const node = new THREE.Vector3();
    const result = skeletons.map((positions) => {
      const local = positions.map((p) => (p ? new THREE.Vector3(...p).applyMatrix4(toLocal) : null));
      const samples: THREE.Vector3[] = [];
      for (const [a, b] of KINECT20_BONES) {
        const pa = local[a], pb = local[b];
        if (!pa || !pb) continue;
        for (let k = 1; k < BONE_STEPS; k++) samples.push(pa.clone().lerp(pb, k / BONE_STEPS));
      }
      const joints = local.map((p) => {
        if (!p) return false;
        let near = false;
        for (let j = 0; j < n; j++) {
          node.fromArray(this.nodes, 3 * j);
          if (node.distanceToSquared(p) < REACH * REACH) { near = true; hot[j] = 1; }
        }
        return near;
      });
      for (const s of samples) {
        for (let j = 0; j < n; j++) {
          node.fromArray(this.nodes, 3 * j);
          if (node.distanceToSquared(s) < REACH * REACH) hot[j] = 1;
        }
      }
      return joints;
    });
    this.hotNodes = 0;
    for (let j = 0; j < n; j++) {
      (hot[j] ? HOT : IDLE).toArray(this.colours, 3 * j);
      this.hotNodes += hot[j];
    }
    (this.points.geometry.getAttribute('color') as THREE.BufferAttribute).needsUpdate = true;
    this.attachableJoints = result[0] ?? [];
    return result;
  }

  dispose(): void {
    this.points.removeFromParent();
    this.points.geometry.dispose();
  }
}
