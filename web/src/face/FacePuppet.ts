// The live face in the 3D scene: the template's topology, vertices rebuilt per frame (Algorithm 2), the
// camera frame as live texture, caricatures as three.js morph targets (the same fields the GLB exports).
// It sits on an anchor (a neck position and orientation per frame): an avatar's neck when it rides on one,
// otherwise a stand beside the possessed mesh.
import * as THREE from 'three';
import type { FaceTemplate } from './FaceTemplate';
import type { FaceShape } from './reconstruct';

export interface FaceAnchor {
  position: THREE.Vector3;
  quaternion: THREE.Quaternion;
  scale?: number;             // the puppet's size (1 = life size)
  overlay?: boolean;          // draw over what is there (an avatar's own head), like a mask
}

const CM = 0.01;

export class FacePuppet {
  readonly mesh: THREE.Mesh<THREE.BufferGeometry, THREE.MeshBasicMaterial>;
  readonly template: FaceTemplate;
  private readonly positions: THREE.BufferAttribute;
  private readonly uvs: THREE.BufferAttribute;
  private readonly turn = new THREE.Quaternion();
  frames = 0;

  constructor(template: FaceTemplate, video: HTMLVideoElement) {
    this.template = template;
    const n = template.vertices.length / 3;
    const g = new THREE.BufferGeometry();
    const rest = new Float32Array(3 * n);
    for (let i = 0; i < n; i++) {
      for (let k = 0; k < 3; k++) rest[3 * i + k] = CM * (template.vertices[3 * i + k] - template.vertices[3 * template.chin + k]);
    }
    this.positions = new THREE.BufferAttribute(rest, 3).setUsage(THREE.DynamicDrawUsage);
    const uv = new Float32Array(2 * n);
    for (let i = 0; i < n; i++) { uv[2 * i] = template.uvs[2 * i]; uv[2 * i + 1] = 1 - template.uvs[2 * i + 1]; }
    this.uvs = new THREE.BufferAttribute(uv, 2).setUsage(THREE.DynamicDrawUsage);
    g.setAttribute('position', this.positions);
    g.setAttribute('uv', this.uvs);
    g.setIndex(new THREE.BufferAttribute(template.triangles, 1));
    g.morphAttributes.position = template.morphs.map((m) => new THREE.BufferAttribute(m.map((x) => CM * x), 3));
    g.morphTargetsRelative = true;
    g.computeBoundingSphere();
    const texture = new THREE.VideoTexture(video);
    texture.colorSpace = THREE.SRGBColorSpace;
    this.mesh = new THREE.Mesh(g, new THREE.MeshBasicMaterial({ map: texture, side: THREE.DoubleSide }));
    this.mesh.name = 'face puppet';
    this.mesh.frustumCulled = false;
    this.mesh.morphTargetInfluences = template.morphNames.map(() => 0);
  }

  /** A new frame: vertices and UVs from the reconstruction; `turn` rotates the face with the head. */
  update(shape: FaceShape, turn: boolean): void {
    this.positions.copyArray(shape.face);
    this.positions.needsUpdate = true;
    this.uvs.copyArray(shape.uvs);
    this.uvs.needsUpdate = true;
    if (turn) {
      const r = shape.pose.rotation;
      this.turn.setFromRotationMatrix(new THREE.Matrix4().set(
        r[0], r[1], r[2], 0, r[3], r[4], r[5], 0, r[6], r[7], r[8], 0, 0, 0, 0, 1));
    } else this.turn.identity();
    this.frames++;
  }

  /** Put the chin on the anchor (per rendered frame). */
  place(anchor: FaceAnchor): void {
    this.mesh.position.copy(anchor.position);
    this.mesh.quaternion.copy(anchor.quaternion).multiply(this.turn);
    this.mesh.scale.setScalar(anchor.scale ?? 1);
    const overlay = anchor.overlay ?? false;
    if (this.mesh.material.depthTest === overlay) {
      this.mesh.material.depthTest = !overlay;
      this.mesh.renderOrder = overlay ? 10 : 0;
    }
  }

  setMorphs(weights: number[]): void {
    weights.forEach((w, k) => { (this.mesh.morphTargetInfluences as number[])[k] = w; });
  }

  /** World positions of some vertices with the morphs applied (what the GPU draws), for tests. */
  worldPositions(indices: number[]): number[][] {
    this.mesh.updateMatrixWorld(true);
    const v = new THREE.Vector3();
    const w = this.mesh.morphTargetInfluences as number[];
    return indices.map((i) => {
      v.fromBufferAttribute(this.positions, i);
      this.template.morphs.forEach((m, k) => {
        v.x += w[k] * CM * m[3 * i]; v.y += w[k] * CM * m[3 * i + 1]; v.z += w[k] * CM * m[3 * i + 2];
      });
      return v.clone().applyMatrix4(this.mesh.matrixWorld).toArray();
    });
  }

  dispose(): void {
    this.mesh.removeFromParent();
    this.mesh.geometry.dispose();
    this.mesh.material.map?.dispose();
    this.mesh.material.dispose();
  }
}
