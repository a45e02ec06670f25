// The 3D view: renderer, camera, orbit controls, lights with ground shadows, and the render loop with
// its frame-rate figures (fps, and the CPU milliseconds spent outside renderer.render).
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

export class Viewport {
  readonly renderer: THREE.WebGLRenderer;
  readonly scene = new THREE.Scene();
  readonly camera: THREE.PerspectiveCamera;
  readonly controls: OrbitControls;
  fps = 0;
  renderMs = 0;
  updateMs = 0;
  frames = 0;
  private frameTimes: number[] = [];
  private readonly callbacks: ((dt: number) => void)[] = [];

  constructor(container: HTMLElement, shadows = true) {
    this.renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.setSize(container.clientWidth, container.clientHeight);
    this.renderer.shadowMap.enabled = shadows;
    this.renderer.shadowMap.type = THREE.PCFShadowMap;
    container.appendChild(this.renderer.domElement);

    this.scene.background = new THREE.Color(0x20242b);
    this.camera = new THREE.PerspectiveCamera(45, container.clientWidth / container.clientHeight, 0.05, 100);
    this.camera.position.set(0.6, 1.6, 5.0);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.target.set(0, 0.9, 0);
    this.controls.update();

    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 1.2));
    const sun = new THREE.DirectionalLight(0xffffff, 2.0);
    sun.position.set(2, 5, 3);
    sun.castShadow = true;
    sun.shadow.mapSize.set(1024, 1024);
    const s = sun.shadow.camera;
    s.left = -3; s.right = 3; s.top = 3; s.bottom = -3; s.near = 0.5; s.far = 15;
    this.scene.add(sun);

    const ground = new THREE.Mesh(new THREE.PlaneGeometry(20, 20), new THREE.ShadowMaterial({ opacity: 0.35 }));
    ground.rotation.x = -Math.PI / 2;
    ground.receiveShadow = true;
    this.scene.add(ground);
    const grid = new THREE.GridHelper(10, 20, 0x556070, 0x39414c);
    (grid.material as THREE.Material).transparent = true;
    (grid.material as THREE.Material).opacity = 0.5;
    this.scene.add(grid);

    window.addEventListener('resize', () => this.resize(container));
  }

  onFrame(callback: (dt: number) => void): void {
    this.callbacks.push(callback);
  }

  start(): void {
    let last = performance.now();
    const tick = () => {
      const now = performance.now();
      const dt = (now - last) / 1000;
      last = now;
      const updateStart = performance.now();
      for (const cb of this.callbacks) cb(dt);
      this.controls.update();
      const renderStart = performance.now();
      this.renderer.render(this.scene, this.camera);
      const end = performance.now();
      this.updateMs = 0.9 * this.updateMs + 0.1 * (renderStart - updateStart);
      this.renderMs = 0.9 * this.renderMs + 0.1 * (end - renderStart);
      this.frames++;
      this.frameTimes.push(now);
      while (this.frameTimes.length && this.frameTimes[0] < now - 2000) this.frameTimes.shift();
      this.fps = this.frameTimes.length > 1
        ? (1000 * (this.frameTimes.length - 1)) / (now - this.frameTimes[0]) : 0;
      requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
  }

  private resize(container: HTMLElement): void {
    this.camera.aspect = container.clientWidth / container.clientHeight;
    this.camera.updateProjectionMatrix();
    this.renderer.setSize(container.clientWidth, container.clientHeight);
  }
}
