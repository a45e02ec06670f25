// Move / rotate (about the vertical) / scale the mesh relative to the user with a gizmo. The server owns
// the placement (all pages share it): a drag sends "place" and the server's state moves every page's mesh.
import * as THREE from 'three';
import { TransformControls } from 'three/examples/jsm/controls/TransformControls.js';
import type { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import type { PlacementState } from '../net/protocol';

export type PlacementMode = 'translate' | 'rotate' | 'scale';

export class PlacementControls {
  readonly holder = new THREE.Group(); // carries the placement matrix; the mesh is its child
  private readonly gizmo: TransformControls;
  private dragging = false;

  constructor(camera: THREE.Camera, dom: HTMLElement, orbit: OrbitControls, scene: THREE.Scene,
              private readonly send: (message: object) => void) {
    scene.add(this.holder);
    this.gizmo = new TransformControls(camera, dom);
    this.gizmo.attach(this.holder);
    this.gizmo.setSize(0.8);
    this.gizmo.addEventListener('dragging-changed', (e) => {
      this.dragging = Boolean((e as unknown as { value: boolean }).value);
      orbit.enabled = !this.dragging;
      if (!this.dragging) this.commit();
    });
    this.gizmo.addEventListener('objectChange', () => this.constrain());
    scene.add(this.gizmo.getHelper());
    this.setMode('translate');
  }

  setMode(mode: PlacementMode): void {
    this.gizmo.setMode(mode);
    this.gizmo.showX = mode !== 'rotate';
    this.gizmo.showZ = mode !== 'rotate';
    this.gizmo.showY = true;
  }

  /** Apply the server's placement (ignored while the user is dragging). */
  apply(p: PlacementState): void {
    if (this.dragging) return;
    this.holder.position.set(p.position[0], p.position[1], p.position[2]);
    this.holder.rotation.set(0, p.yaw, 0);
    this.holder.scale.setScalar(p.scale);
    this.holder.updateMatrixWorld(true);
  }

  /** Keep the placement a uniform scale and a yaw, as the server expects. */
  private constrain(): void {
    const s = this.holder.scale;
    const uniform = this.gizmo.axis === 'X' ? s.x : this.gizmo.axis === 'Z' ? s.z : s.y;
    s.setScalar(Math.max(0.05, uniform));
    const yaw = new THREE.Euler().setFromQuaternion(this.holder.quaternion, 'YXZ').y;
    this.holder.rotation.set(0, yaw, 0);
  }

  private commit(): void {
    const p = this.holder.position;
    const yaw = new THREE.Euler().setFromQuaternion(this.holder.quaternion, 'YXZ').y;
    this.send({ type: 'place', scale: this.holder.scale.x, position: [p.x, p.y, p.z], yaw });
  }
}
