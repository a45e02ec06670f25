// The physics world drawn with three.js: instanced boxes and balls (with shadows) and, when asked, the
// mesh's sphere proxies as see-through wireframe balls.
import * as THREE from 'three';
import { MAX_BALLS, type PhysicsWorld } from './PhysicsWorld';

const BOX_COLOURS = [0xe07a5f, 0xf2cc8f, 0x81b29a, 0x3d85c6];

export class PhysicsView {
  readonly group = new THREE.Group();
  private boxes: THREE.InstancedMesh | null = null;
  private readonly balls: THREE.InstancedMesh;
  private proxies: THREE.InstancedMesh | null = null;
  private readonly matrix = new THREE.Matrix4();
  private readonly position = new THREE.Vector3();
  private readonly quaternion = new THREE.Quaternion();
  private readonly scale = new THREE.Vector3();
  showSpheres = false;

  constructor(scene: THREE.Scene) {
    this.balls = new THREE.InstancedMesh(new THREE.SphereGeometry(1, 20, 14),
      new THREE.MeshStandardMaterial({ color: 0xd7263d, roughness: 0.4 }), MAX_BALLS);
    this.balls.castShadow = true;
    this.balls.count = 0;
    this.balls.frustumCulled = false;
    this.group.add(this.balls);
    scene.add(this.group);
  }

  /** New instanced meshes for a freshly built world (boxes and proxies change count with it). */
  build(world: PhysicsWorld | null): void {
    for (const m of [this.boxes, this.proxies]) {
      if (!m) continue;
      m.removeFromParent();
      m.geometry.dispose();
      (m.material as THREE.Material).dispose();
    }
    this.boxes = this.proxies = null;
    this.balls.count = 0;
    if (!world) return;
    if (world.boxes.length) {
      this.boxes = new THREE.InstancedMesh(new THREE.BoxGeometry(2, 2, 2),
        new THREE.MeshStandardMaterial({ roughness: 0.8 }), world.boxes.length);
      world.boxes.forEach((_, i) => this.boxes?.setColorAt(i, new THREE.Color(BOX_COLOURS[i % BOX_COLOURS.length])));
      this.boxes.castShadow = this.boxes.receiveShadow = true;
      this.boxes.frustumCulled = false;
      this.group.add(this.boxes);
    }
    if (world.proxies.length) {
      this.proxies = new THREE.InstancedMesh(new THREE.SphereGeometry(1, 12, 8),
        new THREE.MeshBasicMaterial({ color: 0x4fc3f7, wireframe: true, transparent: true, opacity: 0.45 }),
        world.proxies.length);
      this.proxies.frustumCulled = false;
      this.group.add(this.proxies);
    }
    this.sync(world);
  }

  /** Copy body poses into the instances. */
  sync(world: PhysicsWorld): void {
    const { matrix, position, quaternion, scale } = this;
    if (this.boxes) {
      world.boxes.forEach(({ body, half }, i) => {
        const p = body.translation();
        const q = body.rotation();
        matrix.compose(position.set(p.x, p.y, p.z), quaternion.set(q.x, q.y, q.z, q.w), scale.setScalar(half));
        this.boxes?.setMatrixAt(i, matrix);
      });
      this.boxes.instanceMatrix.needsUpdate = true;
    }
    world.balls.forEach(({ body, radius }, i) => {
      const p = body.translation();
      const q = body.rotation();
      matrix.compose(position.set(p.x, p.y, p.z), quaternion.set(q.x, q.y, q.z, q.w), scale.setScalar(radius));
      this.balls.setMatrixAt(i, matrix);
    });
    this.balls.count = world.balls.length;
    this.balls.instanceMatrix.needsUpdate = true;
    if (this.proxies) {
      this.proxies.visible = this.showSpheres;
      if (this.showSpheres) {
        quaternion.identity();
        world.proxies.forEach((body, i) => {
          const p = body.translation();
          matrix.compose(position.set(p.x, p.y, p.z), quaternion, scale.setScalar(body.collider(0).radius()));
          this.proxies?.setMatrixAt(i, matrix);
        });
        this.proxies.instanceMatrix.needsUpdate = true;
      }
    }
  }
}
