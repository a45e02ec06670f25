// The studio's face: a "Face" button (webcam → Face Mesh → Algorithm 2 → the puppet), caricature sliders
// and presets, and face takes (landmarks per frame, exported by the server as an animated, textured GLB
// with the caricature morph targets). It only needs the page's camera, scene and panel.
import * as THREE from 'three';
import './face.css';
import type { Camera } from '../capture/Camera';
import type { Viewport } from '../scene/Viewport';
import { type FaceAnchor, FacePuppet } from './FacePuppet';
import { type FaceTemplate, fetchFaceTemplate } from './FaceTemplate';
import { FaceTracker } from './FaceTracker';
import { reconstructFace } from './reconstruct';

const MAX_TAKE_FRAMES = 1800;  // the server's limit (kinetre/studio/face_routes.py)

/** Where the puppet stands when no avatar carries it: beside the possessed mesh, 3× life size. */
export const STAND: FaceAnchor = { position: new THREE.Vector3(1.1, 1.2, 0.3), quaternion: new THREE.Quaternion(), scale: 3 };

interface Recording { frames: (number[] | null)[]; start: number; image: string | null; width: number; height: number }

export class FaceController {
  readonly tracker = new FaceTracker();
  template: FaceTemplate | null = null;
  puppet: FacePuppet | null = null;
  /** Set by whoever carries the face (an avatar's neck, per frame); null: the puppet's stand. */
  anchor: (() => FaceAnchor | null) | null = null;
  on = false;
  turn = true;
  tracked = 0;
  lost = 0;
  landmarksPerSecond = 0;
  weights: number[] = [];
  lastTake: { frames: number; bytes: number; url: string } | null = null;
  private readonly section: HTMLElement;
  private readonly sliders: HTMLInputElement[] = [];
  private readonly button: HTMLButtonElement;
  private readonly recordButton: HTMLButtonElement;
  private readonly downloads: HTMLElement;
  private recording: Recording | null = null;
  private rate: number[] = [];

  constructor(private readonly camera: Camera, private readonly viewport: Viewport, area: HTMLElement,
              private readonly say: (text: string, error?: boolean) => void) {
    this.section = document.createElement('div');
    this.section.className = 'face-controls';
    this.section.innerHTML = `
      <div class="row">
        <button id="face" title="G: your face, live, on a puppet">Face</button>
        <a href="annotate/" target="_blank" title="annotate a photo the tracker misses">Annotate…</a>
      </div>
      <div id="face-in-use" hidden>
        <div class="row">
          <select id="face-preset" title="caricature presets"></select>
          <button id="face-record" title="record a face take (GLB with the caricature morphs)">Record face</button>
        </div>
        <div id="face-sliders"></div>
        <div id="face-downloads"></div>
      </div>`;
    area.appendChild(this.section);
    const $ = <T extends HTMLElement>(id: string) => this.section.querySelector(`#${id}`) as T;
    this.button = $<HTMLButtonElement>('face');
    this.recordButton = $<HTMLButtonElement>('face-record');
    this.downloads = $('face-downloads');
    this.button.addEventListener('click', () => void this.toggle());
    this.recordButton.addEventListener('click', () => void this.toggleRecord());
    window.addEventListener('keydown', (e) => {
      if (e.key.toLowerCase() === 'g' && !(e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement) && !e.repeat) void this.toggle();
    });
    void fetchFaceTemplate().then((t) => this.buildSliders(t, $('face-sliders'), $<HTMLSelectElement>('face-preset')))
      .catch((err) => this.say(`face: ${(err as Error).message}`, true));
    viewport.onFrame(() => this.place());
  }

  private buildSliders(t: FaceTemplate, box: HTMLElement, presets: HTMLSelectElement): void {
    this.template = t;
    this.weights = t.morphNames.map(() => 0);
    t.morphNames.forEach((name, k) => {
      const label = document.createElement('label');
      label.className = 'face-slider';
      label.textContent = name;
      const input = document.createElement('input');
      Object.assign(input, { type: 'range', min: '-1', max: '1.5', step: '0.05', value: '0', id: `face-${name}` });
      input.addEventListener('input', () => { this.weights[k] = Number(input.value); this.puppet?.setMorphs(this.weights); });
      label.appendChild(input);
      box.appendChild(label);
      this.sliders.push(input);
    });
    for (const name of Object.keys(t.presets)) presets.add(new Option(name, name));
    presets.addEventListener('change', () => { this.setMorphs(t.presets[presets.value]); presets.blur(); });
  }

  setMorphs(weights: number[]): void {
    this.weights = [...weights];
    this.sliders.forEach((s, k) => { s.value = String(weights[k]); });
    this.puppet?.setMorphs(this.weights);
  }

  async toggle(): Promise<void> {
    if (this.on) {
      this.on = false;
      this.button.classList.remove('active');
      return;
    }
    try {
      this.say('starting the camera and the face tracker…');
      const template = await fetchFaceTemplate();
      if (!this.camera.running) await this.camera.start();
      await this.tracker.init();
      if (!this.puppet) {
        this.puppet = new FacePuppet(template, this.camera.video);
        this.puppet.setMorphs(this.weights);
        this.viewport.scene.add(this.puppet.mesh);
        (this.section.querySelector('#face-in-use') as HTMLElement).hidden = false;  // a face to shape and record
      }
      this.on = true;
      this.button.classList.add('active');
      this.say('face on: look at the camera; the sliders and presets make caricatures');
      void this.loop();
    } catch (err) {
      this.say(`face: ${(err as Error).message}`, true);
    }
  }

  private async loop(): Promise<void> {
    const video = this.camera.video;
    while (this.on && this.camera.running && this.template && this.puppet) {
      const landmarks = await this.tracker.detect(video).catch(() => null);
      const now = performance.now();
      this.rate = [...this.rate.filter((t) => now - t < 2000), now];
      this.landmarksPerSecond = this.rate.length > 1 ? (1000 * (this.rate.length - 1)) / (now - this.rate[0]) : 0;
      const shape = landmarks && reconstructFace(this.template, landmarks, video.videoWidth, video.videoHeight);
      if (shape) {
        this.puppet.update(shape, this.turn);   // tracking loss keeps the last good face
        this.tracked++;
      } else this.lost++;
      if (this.recording) this.record(shape ? landmarks : null, video);
      await new Promise((resolve) => setTimeout(resolve, 0));
    }
  }

  private place(): void {
    if (!this.puppet) return;
    this.puppet.place(this.anchor?.() ?? STAND);
  }

  // --- face takes -----------------------------------------------------------------------------------
  private record(landmarks: Float32Array | null, video: HTMLVideoElement): void {
    const r = this.recording as Recording;
    if (landmarks && r.image === null) {
      // the texture of the exported face: the first frame with a face, at the camera's resolution
      const canvas = document.createElement('canvas');
      canvas.width = video.videoWidth;
      canvas.height = video.videoHeight;
      (canvas.getContext('2d') as CanvasRenderingContext2D).drawImage(video, 0, 0);
      r.image = canvas.toDataURL('image/jpeg', 0.9).split(',')[1];
      r.width = canvas.width;
      r.height = canvas.height;
    }
    if (r.image !== null) r.frames.push(landmarks ? Array.from(landmarks, (x) => Math.round(x * 100) / 100) : null);
    if (r.frames.length >= MAX_TAKE_FRAMES) void this.toggleRecord();
  }

  async toggleRecord(): Promise<void> {
    if (!this.recording) {
      if (!this.on) await this.toggle();
      this.recording = { frames: [], start: performance.now(), image: null, width: 0, height: 0 };
      this.recordButton.classList.add('active');
      this.say('recording your face… press Record face again to stop');
      return;
    }
    const r = this.recording;
    this.recording = null;
    this.recordButton.classList.remove('active');
    if (!r.image || !r.frames.length) { this.say('face take: no face was seen, nothing to export', true); return; }
    const fps = Math.max(1, Math.min(60, (1000 * r.frames.length) / (performance.now() - r.start)));
    try {
      this.say(`exporting a face take of ${r.frames.length} frames…`);
      const res = await fetch('api/face/export', {
        method: 'POST', headers: { 'Content-Type': 'application/json' },
        body: JSON.stringify({ width: r.width, height: r.height, fps, frames: r.frames, image: r.image,
          weights: this.weights, turn: this.turn }),
      });
      if (!res.ok) throw new Error(((await res.json()) as { error?: string }).error ?? `HTTP ${res.status}`);
      const glb = await res.blob();
      if (this.lastTake) URL.revokeObjectURL(this.lastTake.url);
      this.lastTake = { frames: r.frames.length, bytes: glb.size, url: URL.createObjectURL(glb) };
      const a = document.createElement('a');
      Object.assign(a, { href: this.lastTake.url, download: 'kinetre-face.glb', textContent: 'Face GLB', className: 'download' });
      this.downloads.replaceChildren(a);
      this.say(`face take: ${r.frames.length} frames at ${fps.toFixed(1)} fps`);
    } catch (err) {
      this.say(`face take: ${(err as Error).message}`, true);
    }
  }
}

/** window.kinetreFace: a read-only view for browser tests (like window.kinetre). */
export function installFaceTestHook(face: FaceController): void {
  (window as unknown as { kinetreFace: object }).kinetreFace = {
    face,
    state() {
      const sample = [0, 1, 10, 33, 61, 152, 263, 291];
      return {
        on: face.on, tracked: face.tracked, lost: face.lost, landmarksPerSecond: face.landmarksPerSecond,
        detectMs: face.tracker.detectMs, weights: face.weights, morphNames: face.template?.morphNames ?? [],
        frames: face.puppet?.frames ?? 0,
        vertices: face.puppet ? face.puppet.worldPositions(sample) : [],
        uvs: face.puppet ? sample.map((i) => Array.from((face.puppet as FacePuppet).mesh.geometry.getAttribute('uv').array.slice(2 * i, 2 * i + 2))) : [],
        take: face.lastTake,
        anchor: face.anchor?.() ? 'avatar' : 'stand',
        chin: face.puppet ? face.puppet.worldPositions([face.template?.chin ?? 152])[0] : null,
      };
    },
    /** Play an exported face GLB in three.js (GLTFLoader + AnimationMixer): world positions of `indices`
     *  at the animation's first `keys` keyframes, as a glTF player shows them. */
    async play(url: string, indices: number[], keys = 4) {
      const { GLTFLoader } = await import('three/examples/jsm/loaders/GLTFLoader.js');
      const gltf = await new GLTFLoader().loadAsync(url);
      let mesh: THREE.Mesh | null = null;
      gltf.scene.traverse((o) => { if ((o as THREE.Mesh).isMesh && !mesh) mesh = o as THREE.Mesh; });
      const mixer = new THREE.AnimationMixer(gltf.scene);
      const clip = gltf.animations[0];
      mixer.clipAction(clip).play();
      const times = Array.from(clip.tracks[0].times.slice(0, keys));
      const v = new THREE.Vector3();
      const positions = times.map((t) => {
        mixer.setTime(t);
        gltf.scene.updateMatrixWorld(true);
        return indices.map((i) => (mesh as THREE.Mesh).getVertexPosition(i, v).applyMatrix4((mesh as THREE.Mesh).matrixWorld).toArray());
      });
      return { times, positions, targets: ((mesh as THREE.Mesh | null)?.morphTargetInfluences ?? []).length };
    },
    reconstruct(landmarks: number[], width: number, height: number) {
      const shape = face.template && reconstructFace(face.template, landmarks, width, height);
      return shape ? { face: Array.from(shape.face), uvs: Array.from(shape.uvs), scale: shape.pose.scale, rotation: shape.pose.rotation } : null;
    },
  };
}
