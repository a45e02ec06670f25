// The mesh skinned on the GPU by its deformation graph: every graph node is a bone, each vertex has the
// 4 node indices/weights of Eq. 2, and the bone matrices are the node affines sent by the server
// (pose.node_matrices). Bones are not in the scene graph and bind matrices are identities, so a bone
// matrix maps a rest vertex straight to its deformed place in the mesh's own frame.
//
// Where a skeleton is inside, the surface turns translucent (paper Fig. 5): the fragment shader gets the
// bone segments in world space and fades the surface near them.
import * as THREE from 'three';
import type { MeshData } from './MeshPayload';

export const MAX_SEGMENTS = 40; // two skeletons × 19 bones, plus room

export class SkinnedGraphMesh {
  readonly mesh: THREE.SkinnedMesh;
  readonly data: MeshData;
  private readonly bones: THREE.Bone[];
  private readonly segmentsA: THREE.Vector3[] = [];
  private readonly segmentsB: THREE.Vector3[] = [];
  private readonly uniforms = {
    uSegmentCount: { value: 0 },
    uSegA: { value: [] as THREE.Vector3[] },
    uSegB: { value: [] as THREE.Vector3[] },
    uInside: { value: 0.12 },
  };
  /** Sequence number of the last transform block applied. */
  seq = 0;

  constructor(data: MeshData) {
    this.data = data;
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(data.positions, 3));
    geometry.setAttribute('normal', new THREE.BufferAttribute(data.normals, 3));
    geometry.setAttribute('skinIndex', new THREE.Uint16BufferAttribute(data.skinIndex, 4));
    geometry.setAttribute('skinWeight', new THREE.BufferAttribute(data.skinWeight, 4));
    geometry.setIndex(new THREE.BufferAttribute(data.faces, 1));
    geometry.computeBoundingSphere();

    for (let i = 0; i < MAX_SEGMENTS; i++) {
      this.segmentsA.push(new THREE.Vector3());
      this.segmentsB.push(new THREE.Vector3());
    }
    this.uniforms.uSegA.value = this.segmentsA;
    this.uniforms.uSegB.value = this.segmentsB;

    const material = new THREE.MeshStandardMaterial({
      color: 0xd9c7a7, roughness: 0.75, metalness: 0.0, transparent: true, side: THREE.DoubleSide,
    });
    material.onBeforeCompile = (shader) => this.injectTranslucency(shader);

    const nodeCount = data.nodes.length / 3;
    this.bones = [];
    for (let j = 0; j < nodeCount; j++) {
      const bone = new THREE.Bone();
      bone.matrixAutoUpdate = false;
      bone.matrixWorldAutoUpdate = false;
      this.bones.push(bone);
    }
    const inverses = this.bones.map(() => new THREE.Matrix4());
    const skeleton = new THREE.Skeleton(this.bones, inverses);
    this.mesh = new THREE.SkinnedMesh(geometry, material);
    this.mesh.bind(skeleton, new THREE.Matrix4());
    this.mesh.bindMode = THREE.DetachedBindMode;
    this.mesh.castShadow = true;
    this.mesh.receiveShadow = true;
    this.mesh.frustumCulled = false; // the rest-pose bounds do not follow the deformation
  }

  get nodeCount(): number {
    return this.bones.length;
  }

  /** Node matrices from a transform block: `rows` holds count × 12 floats (rows 0–2, row-major). */
  setNodeMatrices(rows: Float32Array, seq: number): void {
    const n = Math.min(this.bones.length, rows.length / 12);
    for (let j = 0; j < n; j++) {
      const r = rows.subarray(12 * j, 12 * j + 12);
      this.bones[j].matrixWorld.set(r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[10], r[11],
        0, 0, 0, 1);
    }
    this.seq = seq;
  }

  /** World positions of the given vertices after skinning (the same formula as the shader). */
  skinnedPositions(indices: number[]): [number, number, number][] {
    const v = new THREE.Vector3();
    this.mesh.updateMatrixWorld();
    return indices.map((i) => {
      v.fromBufferAttribute(this.mesh.geometry.getAttribute('position') as THREE.BufferAttribute, i);
      this.mesh.applyBoneTransform(i, v);
      v.applyMatrix4(this.mesh.matrixWorld);
      return [v.x, v.y, v.z];
    });
  }

  /** Bone segments (world space) near which the surface turns see-through. */
  setSkeletonSegments(segments: [THREE.Vector3, THREE.Vector3][]): void {
    const n = Math.min(segments.length, MAX_SEGMENTS);
    for (let i = 0; i < n; i++) {
      this.segmentsA[i].copy(segments[i][0]);
      this.segmentsB[i].copy(segments[i][1]);
    }
    this.uniforms.uSegmentCount.value = n;
  }

  private injectTranslucency(shader: THREE.WebGLProgramParametersWithUniforms): void {
    Object.assign(shader.uniforms, this.uniforms);
    shader.vertexShader = shader.vertexShader
      .replace('#include <common>', '#include <common>\nvarying vec3 vKinetreWorld;')
      .replace('#include <worldpos_vertex>',
        '#include <worldpos_vertex>\nvKinetreWorld = (modelMatrix * vec4(transformed, 1.0)).xyz;');
    shader.fragmentShader = shader.fragmentShader
      .replace('#include <common>', `#include <common>
varying vec3 vKinetreWorld;
uniform int uSegmentCount;
uniform vec3 uSegA[${MAX_SEGMENTS}];
uniform vec3 uSegB[${MAX_SEGMENTS}];
uniform float uInside;
float kinetreSkeletonDistance(vec3 p) {
  float d = 1e9;
  for (int i = 0; i < ${MAX_SEGMENTS}; i++) {
    if (i >= uSegmentCount) break;
    vec3 ab = uSegB[i] - uSegA[i];
    float h = clamp(dot(p - uSegA[i], ab) / max(dot(ab, ab), 1e-8), 0.0, 1.0);
    d = min(d, length(p - uSegA[i] - h * ab));
  }
  return d;
}`)
      .replace('#include <dithering_fragment>', `#include <dithering_fragment>
gl_FragColor.a *= mix(0.3, 1.0, smoothstep(uInside, uInside + 0.15, kinetreSkeletonDistance(vKinetreWorld)));`);
  }

  dispose(): void {
    this.mesh.geometry.dispose();
    (this.mesh.material as THREE.Material).dispose();
    this.mesh.skeleton.dispose();
  }
}
