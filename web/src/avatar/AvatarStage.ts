// A rigged humanoid avatar beside the possessed mesh, driven by its own bones (Algorithm 1, retarget.ts)
// from the webcam skeleton or the sample motion; three.js's SkinnedMesh does the avatar's own LBS.
// A skinned glTF/VRM dropped on the page comes here first: the server maps its bones; a humanoid becomes
// the avatar, one with an incomplete map opens the map editor, a non-humanoid (a fox) is left to
// possession with a message saying so. Recording keeps the frames that drove the avatar, with their hands
// and face; the server retargets them again and writes the take as GLB (fingers and morph weights too) and BVH.
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { handsFaceFields, type HandsFaceFields } from '../net/handsFace';
import type { Vec3 } from '../net/protocol';
import { AvatarMapEditor } from './AvatarMapEditor';
import { applyExpressions, expressionWeights, mapExpressions, type ExpressionMap, type MorphHolder } from './Expressions';
import { FingerRetargeter, fingerChains, type Hand } from './Fingers';
import { add, mv, Retargeter, type RetargetPlan, type V3 } from './retarget';

export const AVATAR_EXTENSIONS = ['.glb', '.gltf', '.vrm'];
const HEIGHT = 1.7; // metres the avatar is shown at
const BESIDE = 1.3; // metres to the right of the possessed mesh
const STALE_MS = 1000; // another source may drive once the current one has been silent this long

export interface AvatarPayload {
  id: number;
  name: string;
  url: string;
  joints: string[];
  nodes: number[];
  map: Record<string, number>;
  how: Record<string, string>;
  missing: string[];
  plan: RetargetPlan | null;
  error?: string;
}

interface Recorded { positions: (Vec3 | null)[]; tracked: boolean[]; extra: HandsFaceFields }

/** What drives the avatar besides the body: hands [left, right] and face blendshapes, when seen. */
export interface HandsAndFace {
  hands?: Hand[];
  face?: Record<string, number> | null;
}

export class AvatarStage {
  readonly holder = new THREE.Group();
  payload: AvatarPayload | null = null;
  editor: AvatarMapEditor | null = null;
  source: string | null = null;
  driven = 0;
  lastError = '';
  private bones: THREE.Object3D[] = [];
  private meshes: THREE.SkinnedMesh[] = [];
  private retargeter: Retargeter | null = null;
  private fingers: FingerRetargeter | null = null;
  private expressions: ExpressionMap | null = null;
  private morphMeshes = new Map<number, MorphHolder[]>();
  private vrmBones: Record<string, number> = {};
  private tipEnds: (V3 | null)[] = [];
  private model: THREE.Object3D | null = null;
  private lastDriven = 0;
  private recording: Recorded[] | null = null;
  private recordStart = 0;
  private readonly section: HTMLElement;

  constructor(scene: THREE.Scene, private readonly panel: HTMLElement,
    private readonly say: (text: string, error?: boolean) => void) {
    scene.add(this.holder);
    this.section = document.createElement('div');
    this.section.id = 'avatar-section';
    this.section.className = 'row';
    this.section.hidden = true;
    this.section.innerHTML = '<span id="avatar-name"></span> <button id="avatar-edit-map">Avatar map</button> '
      + '<button id="avatar-remove">Remove avatar</button> <a id="avatar-map-file" class="download" hidden>map JSON</a>';
    panel.appendChild(this.section);
    (this.section.querySelector('#avatar-edit-map') as HTMLButtonElement).addEventListener('click', () => this.openEditor());
    (this.section.querySelector('#avatar-remove') as HTMLButtonElement).addEventListener('click', () => this.remove());
  }

  /** True when `file` was taken as an avatar (or its map is being completed); false to load it as a mesh. */
  async tryUpload(file: File): Promise<boolean> {
    const name = file.name.toLowerCase();
    this.lastError = '';
    if (!AVATAR_EXTENSIONS.some((e) => name.endsWith(e))) return false;
    if (!name.endsWith('.vrm') && !(await hasSkin(file))) return false; // an unrigged glTF: a mesh to possess
    const r = await fetch(`api/avatar?name=${encodeURIComponent(file.name)}`, { method: 'POST', body: file });
    const body = (await r.json()) as AvatarPayload & { error?: string };
    if (r.status === 400) {
      if (name.endsWith('.vrm')) throw new Error(body.error ?? `${file.name}: not an avatar`);
      this.say(`${body.error} — loading it as a mesh to possess instead`, true);
      this.lastError = body.error ?? '';
      return false;
    }
    if (!r.ok && r.status !== 422) throw new Error(body.error ?? `${file.name}: upload failed (HTTP ${r.status})`);
    await this.load(body);
    if (r.status === 422) {
      this.say(body.error ?? 'complete the avatar map', true);
      this.openEditor();
    } else {
      // a partial map drives what maps; the joints it lacks follow their parents
      const loose = body.missing.length ? `; not mapped (they follow their parents): ${body.missing.join(', ')}` : '';
      this.say(`avatar ${body.name} ready: it follows the camera skeleton or the sample motion${loose}`);
    }
    return true;
  }

  /** Show the avatar of `payload` (replacing any other). */
  async load(payload: AvatarPayload): Promise<void> {
    const gltf = await new GLTFLoader().loadAsync(payload.url.replace(/^\//, ''));
    this.clear();
    this.payload = payload;
    this.model = gltf.scene;
    this.bones = await Promise.all(payload.nodes.map((n) => gltf.parser.getDependency('node', n) as Promise<THREE.Object3D>));
    this.meshes = [];
    gltf.scene.traverse((o) => {
      if ((o as THREE.SkinnedMesh).isSkinnedMesh) {
        const m = o as THREE.SkinnedMesh;
        m.frustumCulled = false; // the avatar walks away from its bind-pose bounds
        m.castShadow = true;
        this.meshes.push(m);
      }
    });
    this.readHandsAndFace(gltf.parser.json, gltf.scene, (o) => gltf.parser.associations.get(o)?.meshes);
    this.holder.add(gltf.scene);
    this.place();
    this.setPlan(payload.plan);
    this.section.hidden = false;
    (this.section.querySelector('#avatar-name') as HTMLElement).textContent = `avatar: ${payload.name}`;
  }

  /** The avatar's VRM finger bones, its end bones' tips and the meshes its expressions move (at load: rest pose). */
  private readHandsAndFace(json: Record<string, unknown>, scene: THREE.Object3D,
    meshOf: (o: THREE.Object3D) => number | undefined): void {
    const nodeJoint = new Map((this.payload?.nodes ?? []).map((n, j) => [n, j]));
    const ext = (json.extensions ?? {}) as {
      VRMC_vrm?: { humanoid?: { humanBones?: Record<string, { node?: number }> } };
      VRM?: { humanoid?: { humanBones?: { bone?: string; node?: number }[] } };
    };
    this.vrmBones = {};
    const human = ext.VRMC_vrm?.humanoid?.humanBones;
    if (human && typeof human === 'object') {
      for (const [name, b] of Object.entries(human)) {
        const j = nodeJoint.get(b?.node ?? -1);
        if (j !== undefined) this.vrmBones[name] = j;
      }
    }
    for (const b of ext.VRM?.humanoid?.humanBones ?? []) {
      const j = nodeJoint.get(b.node ?? -1);
      if (b.bone && j !== undefined && !(b.bone in this.vrmBones)) this.vrmBones[b.bone] = j;
    }
    // a tip bone points at its first child node, which follows it rigidly: offset = rest⁻¹ · child rest
    scene.updateMatrixWorld(true);
    this.tipEnds = this.bones.map((bone) => {
      const child = bone.children[0];
      if (!child) return null;
      const offset = new THREE.Matrix4().copy(bone.matrixWorld).invert().multiply(child.matrixWorld);
      return [offset.elements[12], offset.elements[13], offset.elements[14]];
    });
    this.expressions = mapExpressions(json as Parameters<typeof mapExpressions>[0]);
    this.morphMeshes = new Map();
    scene.traverse((o) => {
      const m = meshOf(o);
      const holder = o as unknown as MorphHolder;
      if (m !== undefined && holder.morphTargetInfluences) {
        this.morphMeshes.set(m, [...(this.morphMeshes.get(m) ?? []), holder]);
      }
    });
  }

  private setPlan(plan: RetargetPlan | null): void {
    this.retargeter = plan ? new Retargeter(plan) : null;
    this.fingers = null;
    if (plan && this.payload) {
      const chains = fingerChains(this.payload.joints, plan.real_parents, this.vrmBones, this.payload.map);
      const fingers = new FingerRetargeter(plan, chains, (j) => {
        const o = this.tipEnds[j];
        return o ? add(mv(plan.bind_linear[j], o), plan.bind_positions[j]) : null;
      });
      this.fingers = fingers.active ? fingers : null;
    }
    if (plan) {
      // show it facing the camera: undo the plan's turn from Kinetre's facing (+Z) to the avatar's
      this.holder.rotation.y = -Math.atan2(plan.align[0][2], plan.align[0][0]);
    }
  }

  /** Stand the avatar on the floor, HEIGHT tall, beside the possessed mesh. */
  private place(): void {
    if (!this.model) return;
    this.holder.scale.setScalar(1);
    this.holder.position.set(0, 0, 0);
    this.holder.updateMatrixWorld(true);
    const box = new THREE.Box3();
    const v = new THREE.Vector3();
    for (const m of this.meshes) {
      const count = m.geometry.attributes.position.count;
      for (let i = 0; i < count; i += Math.max(1, Math.floor(count / 2000))) {
        box.expandByPoint(m.getVertexPosition(i, v).applyMatrix4(m.matrixWorld));
      }
    }
    const size = box.getSize(new THREE.Vector3());
    const s = size.y > 0 ? HEIGHT / size.y : 1;
    const centre = box.getCenter(new THREE.Vector3());
    this.model.position.set(-centre.x, -box.min.y, -centre.z);
    this.holder.scale.setScalar(s);
    this.holder.position.set(BESIDE, 0, 0);
  }

  /** One skeleton frame from `client` ('me' for this page's camera, which always wins). */
  drive(positions: (Vec3 | null)[], tracked: boolean[], client: string, extra: HandsAndFace = {}): void {
    if (!this.retargeter) return;
    const now = performance.now();
    if (this.source !== client && client !== 'me' && this.source !== null && now - this.lastDriven < STALE_MS) return;
    if (this.source !== client) { this.retargeter.reset(); this.fingers?.reset(); }
    this.source = client;
    this.lastDriven = now;
    const body = this.retargeter.frame(positions, tracked);
    const frame = this.fingers ? this.fingers.frame(body, extra.hands ?? [null, null]) : body; // unseen: held
    if (extra.face && this.expressions) applyExpressions(expressionWeights(this.expressions, extra.face), this.morphMeshes);
    const m = new THREE.Matrix4();
    frame.local.forEach((l, j) => {
      m.set(l[0][0], l[0][1], l[0][2], l[0][3], l[1][0], l[1][1], l[1][2], l[1][3],
        l[2][0], l[2][1], l[2][2], l[2][3], 0, 0, 0, 1);
      const bone = this.bones[j];
      m.decompose(bone.position, bone.quaternion, bone.scale);
    });
    this.driven++;
    if (this.recording) {
      this.recording.push({ positions: positions.map((p) => (p ? [...p] as Vec3 : null)), tracked: [...tracked],
        extra: handsFaceFields(extra.hands as (Vec3[] | null)[] | undefined, extra.face) });
    }
  }

  startRecording(): void {
    if (!this.retargeter) return;
    this.recording = [];
    this.recordStart = performance.now();
  }

  /** Ends a recording; the take's download links, or [] when no avatar was driven. */
  async stopRecording(): Promise<{ label: string; href: string; file: string }[]> {
    const frames = this.recording;
    this.recording = null;
    if (!frames || !frames.length || !this.payload) return [];
    const seconds = (performance.now() - this.recordStart) / 1000;
    const fps = Math.min(240, Math.max(1, Math.round((10 * frames.length) / Math.max(seconds, 1e-3)) / 10));
    const r = await fetch(`api/avatars/${this.payload.id}/takes`, {
      method: 'POST', headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify({ fps, positions: frames.map((f) => f.positions), tracked: frames.map((f) => f.tracked),
        hands: frames.map((f) => f.extra.hands ?? null), blendshapes: frames.map((f) => f.extra.blendshapes ?? null) }),
    });
    const body = (await r.json()) as { files?: Record<string, string>; take?: number; error?: string };
    if (!r.ok || !body.files) throw new Error(body.error ?? `avatar take: HTTP ${r.status}`);
    return Object.entries(body.files).map(([kind, href]) => ({
      label: `avatar ${kind.toUpperCase()}`, href, file: `kinetre-avatar-${body.take}.${kind}`,
    }));
  }

  openEditor(): void {
    const p = this.payload;
    if (!p) return;
    this.editor?.dispose();
    this.editor = new AvatarMapEditor(this.panel, p.joints, p.map, p.missing, (table) => void this.saveMap(table),
      () => { this.editor?.dispose(); this.editor = null; });
  }

  private async saveMap(table: Record<string, string>): Promise<void> {
    if (!this.payload) return;
    const r = await fetch(`api/avatars/${this.payload.id}/map`, {
      method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify({ kinect20: table }),
    });
    const body = (await r.json()) as AvatarPayload & { error?: string };
    if (r.status === 400 || (!r.ok && r.status !== 422)) {
      this.say(body.error ?? `avatar map: HTTP ${r.status}`, true);
      return;
    }
    this.payload = body;
    this.setPlan(body.plan);
    if (r.status === 422) {
      this.say(body.error ?? 'the map is still incomplete', true);
      this.openEditor();
      return;
    }
    this.editor?.dispose();
    this.editor = null;
    // the saved map, to keep next to one's own copy of the avatar (the server's copy goes with the studio)
    const link = this.section.querySelector('#avatar-map-file') as HTMLAnchorElement;
    link.href = `api/avatars/${body.id}/map`;
    link.download = `${body.name}.kinetre-map.json`;
    link.hidden = false;
    this.say(`avatar map saved next to ${body.name}: the avatar follows the skeleton`);
  }

  private clear(): void {
    (this.section.querySelector('#avatar-map-file') as HTMLElement).hidden = true;
    this.model?.removeFromParent();
    this.model = null;
    this.bones = [];
    this.meshes = [];
    this.retargeter = null;
    this.fingers = null;
    this.expressions = null;
    this.morphMeshes = new Map();
    this.source = null;
  }

  remove(): void {
    this.clear();
    this.payload = null;
    this.editor?.dispose();
    this.editor = null;
    this.section.hidden = true;
  }

  /** The avatar's bone mapped to a Kinect-20 joint (e.g. 'ShoulderCenter'), or null (a face rides on it). */
  bone(kinectJoint: string): THREE.Object3D | null {
    const j = this.retargeter ? this.payload?.map[kinectJoint] : undefined;
    return j === undefined ? null : this.bones[j] ?? null;
  }

  /** For tests: what is loaded, who drives it, and a sample of skinned vertices (world, metres). */
  state(count = 48): object {
    const vertices: number[][] = [];
    if (this.meshes.length) {
      this.holder.updateMatrixWorld(true);
      const v = new THREE.Vector3();
      for (const m of this.meshes) m.skeleton.update();
      const all = this.meshes.flatMap((m) => {
        const n = m.geometry.attributes.position.count;
        return Array.from({ length: Math.min(count, n) }, (_, i) => [m, Math.floor((i * n) / Math.min(count, n))] as const);
      });
      for (const [m, i] of all.slice(0, count)) {
        m.getVertexPosition(i, v).applyMatrix4(m.matrixWorld);
        vertices.push([v.x, v.y, v.z]);
      }
    }
    return {
      id: this.payload?.id ?? null, name: this.payload?.name ?? null, missing: this.payload?.missing ?? [],
      ready: Boolean(this.retargeter), source: this.source, driven: this.driven, editor: Boolean(this.editor),
      recording: this.recording !== null, lastError: this.lastError, vertices,
      fingers: Boolean(this.fingers), expressions: this.expressions?.how ?? null,
      // each driven finger bone's local rotation (x, y, z, w), and the largest weight of each morph target
      fingerBones: Object.fromEntries((this.fingers?.joints ?? []).map((j) => [this.payload?.joints[j] ?? j, this.bones[j].quaternion.toArray()])),
      morphs: this.morphWeights(),
    };
  }

  private morphWeights(): Record<string, number> {
    const out: Record<string, number> = {};
    for (const holders of this.morphMeshes.values()) {
      for (const h of holders as (MorphHolder & { morphTargetDictionary?: Record<string, number> })[]) {
        for (const [name, t] of Object.entries(h.morphTargetDictionary ?? {})) {
          out[name] = Math.max(out[name] ?? 0, h.morphTargetInfluences?.[t] ?? 0);
        }
      }
    }
    return out;
  }
}

/** Does a .glb/.gltf file have a skin? (Reads its JSON only.) */
async function hasSkin(file: File): Promise<boolean> {
  const head = new DataView(await file.slice(0, 20).arrayBuffer());
  let json: { skins?: unknown[] };
  try {
    if (head.byteLength >= 20 && head.getUint32(0, true) === 0x46546c67) {
      const length = head.getUint32(12, true);
      json = JSON.parse(await file.slice(20, 20 + length).text());
    } else {
      json = JSON.parse(await file.text());
    }
  } catch {
    return false; // not parseable here: the mesh loader will say what is wrong
  }
  return Array.isArray(json.skins) && json.skins.length > 0;
}
