// A tracked Kinect-20 skeleton drawn as joint spheres and bone sticks. Joints that would attach if the
// user said "possess" now are highlighted (rigging view); untracked joints are hidden.
import * as THREE from 'three';
import { JOINT_COUNT, KINECT20_BONES } from '../capture/kinect20';
import type { Vec3 } from '../net/protocol';

const ATTACH_COLOUR = new THREE.Color(0xff8a00);

export class SkeletonFigure {
  readonly group = new THREE.Group();
  private readonly joints: THREE.Mesh[] = [];
  private readonly sticks: THREE.LineSegments;
  private readonly baseColour: THREE.Color;
  positions: (Vec3 | null)[] = new Array(JOINT_COUNT).fill(null);
  updatedAt = 0;

  constructor(colour: number) {
    this.baseColour = new THREE.Color(colour);
    const sphere = new THREE.SphereGeometry(0.035, 10, 8);
    for (let j = 0; j < JOINT_COUNT; j++) {
      const m = new THREE.Mesh(sphere, new THREE.MeshBasicMaterial({ color: this.baseColour, depthTest: false }));
      m.renderOrder = 10; // drawn over the mesh: the skeleton is usually inside it
      m.castShadow = true;
      this.joints.push(m);
      this.group.add(m);
    }
    const lineGeometry = new THREE.BufferGeometry();
    lineGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(KINECT20_BONES.length * 6), 3));
    this.sticks = new THREE.LineSegments(lineGeometry,
      new THREE.LineBasicMaterial({ color: this.baseColour, depthTest: false, transparent: true, opacity: 0.9 }));
    this.sticks.renderOrder = 9;
    this.sticks.frustumCulled = false;
    this.group.add(this.sticks);
  }

  update(positions: (Vec3 | null)[], attachable: boolean[] = []): void {
    this.positions = positions;
    this.updatedAt = performance.now();
    positions.forEach((p, j) => {
      const joint = this.joints[j];
      joint.visible = p !== null;
      if (p) joint.position.set(p[0], p[1], p[2]);
      (joint.material as THREE.MeshBasicMaterial).color.copy(attachable[j] ? ATTACH_COLOUR : this.baseColour);
      joint.scale.setScalar(attachable[j] ? 1.5 : 1.0);
    });
    const attr = this.sticks.geometry.getAttribute('position') as THREE.BufferAttribute;
    KINECT20_BONES.forEach(([a, b], i) => {
      const pa = positions[a], pb = positions[b];
      const ok = pa && pb;
      attr.setXYZ(2 * i, ok ? pa[0] : 0, ok ? pa[1] : -100, ok ? pa[2] : 0);
      attr.setXYZ(2 * i + 1, ok ? pb[0] : 0, ok ? pb[1] : -100, ok ? pb[2] : 0);
    });
    attr.needsUpdate = true;
  }

  /** Bone segments with both ends tracked, in world space. */
  segments(): [THREE.Vector3, THREE.Vector3][] {
    return KINECT20_BONES.flatMap(([a, b]) => {
      const pa = this.positions[a], pb = this.positions[b];
      return pa && pb ? [[new THREE.Vector3(...pa), new THREE.Vector3(...pb)] as [THREE.Vector3, THREE.Vector3]] : [];
    });
  }

  dispose(): void {
    this.group.removeFromParent();
    this.sticks.geometry.dispose();
  }
}
