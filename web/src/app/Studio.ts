// The page's wiring along the data path: this page's capture (CaptureLoop) → its skeleton channel on the
// socket → the server's node transforms → each of the scene's meshes skinned on the GPU with its own, with
// the other users' skeletons, the rigging view, an avatar, a face, physics (Playground), voice, and takes
// (TakeSession). Every mesh is a MeshView of one map, skinned by its own transform blocks and standing where
// the server places it; every mesh pushes the physics' boxes and balls, the mesh selected in the mesh list
// (at first the first listed) carries the gizmo, the up axis and the rigging preview, and each person in view
// possesses the mesh chosen in the people list.
import * as THREE from 'three';
import { Camera } from '../capture/Camera';
import { FaceController, installFaceTestHook } from '../face/FaceController';
import { neckAnchor } from '../face/neckAnchor';
import { JOINT_COUNT } from '../capture/kinect20';
import { faceScores, handsFaceFields } from '../net/handsFace';
import type { MeshState, PlacementState, SceneState, ServerMessage, SkeletonMessage, TransformBlock, Vec3 } from '../net/protocol';
import { StudioSocket } from '../net/StudioSocket';
import { AvatarStage } from '../avatar/AvatarStage';
import { Playground, type ShownMesh } from '../physics/Playground';
import { AttachPreview } from '../rigging/AttachPreview';
import { MeshList } from '../rigging/MeshList';
import { MeshUploader } from '../rigging/MeshUploader';
import { PlacementControls } from '../rigging/PlacementControls';
import { fetchMesh } from '../scene/MeshPayload';
import { SkeletonFigure } from '../scene/SkeletonFigure';
import { SkinnedGraphMesh } from '../scene/SkinnedGraphMesh';
import { Viewport } from '../scene/Viewport';
import { Panel } from '../ui/Panel';
import { type MeshChoice, PeopleList } from '../ui/PeopleList';
import { JointMapControl } from '../rigging/JointMapControl';
import { MotionFileControl } from '../ui/MotionFileControl';
import { PuppetControl, possessMessage, puppetFromQuery } from '../rigging/PuppetControl';
import { UpAxisControl } from '../rigging/UpAxisControl';
import { VoiceListener, type VoiceResult } from '../voice/VoiceListener';
import { CaptureLoop, type UserFrame } from './CaptureLoop';
import { statusLine } from './StatusLine';
import { TakeSession } from './TakeSession';

const OTHER_COLOURS = [0x7fdbff, 0xb10dc9, 0x2ecc40, 0xffdc00];
const MY_COLOUR = 0xffffff;
const STALE_MS = 2000; // a remote skeleton not updated for this long disappears

/** One of the scene's meshes, skinned by its own transform blocks. */
export interface MeshView {
  graph: SkinnedGraphMesh;
  holder: THREE.Group; // carries the mesh's placement matrix (the selected mesh hangs in the gizmo's instead)
}

function placeHolder(holder: THREE.Group, p: PlacementState): void {
  holder.matrixAutoUpdate = false;
  holder.matrix.fromArray(p.matrix);
  holder.updateMatrixWorld(true);
}

export class Studio {
  readonly socket: StudioSocket;
  readonly viewport: Viewport;
  readonly panel: Panel;
  readonly placement: PlacementControls;
  readonly camera: Camera;
  readonly capture: CaptureLoop;
  readonly voice: VoiceListener;
  readonly takes: TakeSession;
  readonly uploader: MeshUploader;
  readonly jointMap: JointMapControl;
  readonly motionFile: MotionFileControl;
  readonly puppet: PuppetControl;
  readonly upAxis: UpAxisControl;
  readonly meshList: MeshList;
  readonly avatars: AvatarStage;
  readonly physics: Playground;
  readonly face: FaceController;
  /** The scene's meshes, by id. */
  readonly views = new Map<number, MeshView>();
  readonly people: PeopleList;
  preview: AttachPreview | null = null;
  state: SceneState | null = null;
  readonly me = new SkeletonFigure(MY_COLOUR);
  readonly others = new Map<string, SkeletonFigure>();
  connected = false;
  sceneLost = false;
  seq = 0;
  lastVoice: VoiceResult | null = null;
  transformsSeen = 0;
  latency: number[] = [];
  private readonly loadingViews = new Set<number>();
  /** The mesh the user selected in the mesh list (null, or gone from the scene: the first listed). */
  selected: number | null = null;
  private previewFor: number | null = null; // the mesh the rigging preview was set up for
  private readonly pending = new Map<number, TransformBlock>(); // by mesh id: blocks for a mesh still loading
  private previewClock = 0;

  constructor(root: HTMLElement) {
    this.viewport = new Viewport(root, !new URLSearchParams(location.search).has('noshadows'));
    this.viewport.scene.add(this.me.group);
    this.me.group.visible = false;
    this.panel = new Panel(root, {
      camera: () => void this.capture.toggle(),
      voice: () => void this.toggleVoice(),
      sample: () => this.socket.send({ type: 'player', on: !this.sampleUser() }),
      possess: () => this.possess(),
      release: () => [{ type: 'release' }, ...this.capture.people.releaseMessages()].forEach((m) => this.socket.send(m)),
      subset: (name) => this.socket.send({ type: 'subset', subset: name }),
      fit: () => this.fitMessages().forEach((m) => this.socket.send(m)),
      mode: (mode) => this.placement.setMode(mode),
      record: () => void this.takes.toggle(),
    });
    const say = (text: string, error?: boolean) => this.panel.setMessage(text, error);
    this.camera = new Camera(root);
    this.capture = new CaptureLoop(this.camera, {
      say,
      running: (on) => { this.panel.setActive('camera', on); this.panel.showDriving(on); },
      user: (frame) => this.onUser(frame),
      send: (message) => this.socket.sendFrame(message),
    });
    this.avatars = new AvatarStage(this.viewport.scene, this.panel.area('avatar'), say);
    // the gizmo moves the selected mesh
    this.placement = new PlacementControls(this.viewport.camera, this.viewport.renderer.domElement,
      this.viewport.controls, this.viewport.scene, (m) => this.socket.send({ ...m, mesh: this.selectedState?.id }));
    this.people = new PeopleList(this.panel.area('body'));
    this.voice = new VoiceListener(() => this.voiceQuery(), (r) => this.onVoice(r));
    this.takes = new TakeSession(this.viewport.renderer.domElement, {
      say,
      downloads: (links) => this.panel.setDownloads(links),
      companion: this.avatars,
      recorded: (take) => this.physics.setTake(take.fps, take.meshes.flatMap((m) => {
        const shown = this.state?.meshes.find((x) => x.id === m.id);  // where it stood while recorded
        return shown && m.files.transforms ? [{ id: m.id, transforms: m.files.transforms, placement: shown.placement.matrix }] : [];
      })),
    });
    this.uploader = new MeshUploader({
      onProgress: (label, f) => this.panel.setProgress(label, f),
      onDone: () => {
        this.panel.setProgress(null);
        // a rigged file refused as an avatar keeps its reason on screen: the user asked for an avatar
        const refusal = this.avatars.lastError;
        this.panel.setMessage(refusal ? `${refusal} — loaded as a mesh instead: fit it to you and possess it`
          : 'mesh ready: fit it to you and possess it', refusal !== '');
      },
      onError: (m) => { this.panel.setProgress(null); this.panel.setMessage(m, true); },
    }, (file) => this.avatars.tryUpload(file));
    this.uploader.bind(root, this.panel.fileInput, this.panel.addInput);
    this.jointMap = new JointMapControl(this.panel.area('body'), say);
    this.motionFile = new MotionFileControl(this.panel.area('scene'), say);
    // a hand chosen while possessing takes over from the body (or the other hand) at once
    this.puppet = new PuppetControl(this.panel.area('body').querySelector('#body-drive') as HTMLElement,
      puppetFromQuery(new URLSearchParams(location.search)), () => {
        this.wantHandsAndFace();
        if (this.possessing) this.possess();
      });
    this.upAxis = new UpAxisControl(this.panel.area('scene'), say);
    this.meshList = new MeshList(this.panel.area('scene'), say, (id) => this.select(id));

    const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}${location.pathname.replace(/[^/]*$/, '')}ws`;
    this.socket = new StudioSocket(url, {
      onMessage: (m) => this.onMessage(m),
      onTransforms: (b) => this.onTransforms(b),
      onConnection: (open) => {
        this.connected = open;
        // draw the other users too; at most 4 messages in flight (see StudioSocket)
        if (open) this.socket.send({ type: 'subscribe', skeletons: true, window: 4 });
        this.updateStatus();
      },
    });
    this.viewport.onFrame(() => this.frame());
    this.physics = new Playground({
      viewport: this.viewport,
      area: this.panel.area('physics'),
      meshes: () => this.shownMeshes(),
      say,
      progress: (label, fraction) => this.panel.setProgress(label, fraction),
    });
    this.face = new FaceController(this.camera, this.viewport, this.panel.area('face'), say);
    this.face.anchor = () => neckAnchor((joint) => this.avatars.bone(joint));  // on an avatar's neck, if any
    installFaceTestHook(this.face);
    this.wantHandsAndFace();
  }

  start(): void {
    this.socket.connect();
    this.viewport.start();
  }

  // --- server messages ------------------------------------------------------------------------------
  private onMessage(m: ServerMessage): void {
    switch (m.type) {
      case 'state': {
        if (this.sceneLostNotice(m)) break;
        const was = this.possessing;
        this.state = m;
        if (this.possessing !== was) {
          this.panel.setMessage(this.possessing
            ? 'you possess the mesh: move! (R or say “release” to let go)'
            : 'released: the mesh is back at rest');
        }
        this.showMeshes(m.meshes);
        this.panel.setActive('sample', this.sampleUser(), undefined);
        this.panel.setActive('possess', this.possessing);
        this.panel.setActive('record', m.recording);
        this.jointMap.show(m.joint_map);
        this.updateStatus();
        break;
      }
      case 'skeleton':
        this.onRemoteSkeleton(m);
        break;
      case 'error':
        this.panel.setMessage(m.message, true);
        break;
      default:
        break;
    }
  }

  /** The selected mesh's state: the one the gizmo, the up axis and the rigging preview work on. */
  get selectedState(): MeshState | null {
    const meshes = this.state?.meshes ?? [];
    return meshes.find((m) => m.id === this.selected) ?? meshes[0] ?? null;
  }

  /** The selected mesh as shown, once loaded. */
  get selectedMesh(): SkinnedGraphMesh | null {
    const selected = this.selectedState;
    return selected ? this.views.get(selected.id)?.graph ?? null : null;
  }

  /** Select mesh `id` (from the mesh list): the gizmo, the up axis and the rigging preview move to it. */
  select(id: number): void {
    this.selected = id;
    if (this.state) this.showMeshes(this.state.meshes);
  }

  /** Every mesh shown, in the scene's order, with the world matrix it is drawn with (for physics). */
  private shownMeshes(): ShownMesh[] {
    return (this.state?.meshes ?? []).flatMap((m) => {
      const view = this.views.get(m.id);
      if (!view) return [];
      return [{ id: m.id, graph: view.graph, matrix: () => {
        const holder = view.graph.mesh.parent ?? view.holder;
        holder.updateMatrixWorld(true);
        return holder.matrixWorld.elements;
      } }];
    });
  }

  private onTransforms(block: TransformBlock): void {
    this.transformsSeen++;
    const view = this.views.get(block.meshId);
    if (block.tSource > 0) this.latency = [...this.latency.slice(-59), Date.now() - block.tSource];
    if (!view) {
      this.pending.set(block.meshId, block); // the mesh is still loading: apply when it arrives
      return;
    }
    this.physics.setTransforms(block.meshId, block.rows);
    if (this.physics.replays(block.meshId)) return; // the replay draws the take's poses
    view.graph.setNodeMatrices(block.rows, block.seq);
  }

  /** Show the scene's meshes where they stand, loading new ones and dropping the ones gone; the selected
   * one hangs in the gizmo's holder, with the rigging preview. */
  private showMeshes(meshes: MeshState[]): void {
    for (const [id, view] of this.views) {
      if (meshes.some((m) => m.id === id)) continue;
      view.graph.mesh.removeFromParent();
      view.holder.removeFromParent();
      view.graph.dispose();
      this.views.delete(id);
    }
    const selected = this.selectedState;
    if (selected) {
      this.placement.apply(selected.placement);
      this.upAxis.show(selected.id, selected.up, selected.up_reason);
    }
    for (const m of meshes) {
      const view = this.views.get(m.id);
      if (!view) {
        void this.loadView(m);
        continue;
      }
      placeHolder(view.holder, m.placement);
      const parent = m.id === selected?.id ? this.placement.holder : view.holder;
      if (view.graph.mesh.parent !== parent) parent.add(view.graph.mesh);
    }
    this.meshList.show(meshes, selected?.id ?? null);
    this.rigSelected();
    this.people.show(this.capture.people.ids, this.capture.people.main, this.meshChoices());
  }

  /** The rigging preview follows the selected mesh. */
  private rigSelected(): void {
    const mesh = this.selectedMesh;
    if (!mesh || mesh.data.id === this.previewFor) return;
    this.previewFor = mesh.data.id;
    this.preview?.points.removeFromParent();
    this.preview?.dispose();
    this.preview = new AttachPreview(mesh.data.nodes);
    this.placement.holder.add(this.preview.points);
    this.updateStatus();
  }

  private async loadView(m: MeshState): Promise<void> {
    if (this.loadingViews.has(m.id)) return;
    this.loadingViews.add(m.id);
    try {
      const data = await fetchMesh(m.url.replace(/^\//, ''));
      if (!this.state?.meshes.some((x) => x.id === m.id)) return; // removed while downloading
      const view = { graph: new SkinnedGraphMesh(data), holder: new THREE.Group() };
      this.viewport.scene.add(view.holder);
      this.views.set(m.id, view);
      const pending = this.pending.get(m.id);
      if (pending) {
        view.graph.setNodeMatrices(pending.rows, pending.seq);
        this.physics.setTransforms(m.id, pending.rows);
      }
      this.pending.delete(m.id);
      this.showMeshes(this.state.meshes);
    } finally {
      this.loadingViews.delete(m.id);
    }
  }

  // --- which mesh each person possesses -----------------------------------------------------------
  meshChoices(): MeshChoice[] {
    return (this.state?.meshes ?? []).map((m) => ({ id: m.id, name: m.name }));
  }

  /** A possess message with the mesh chosen for its person (the page's own user: the main person). */
  private withMesh(m: object): object {
    const person = (m as { person?: number }).person;
    const mesh = this.people.meshOf(person ?? this.capture.people.main, this.meshChoices());
    return mesh === null ? m : { ...m, mesh };
  }

  /** "Fit to me": each chosen mesh stands where the first person (the page's own user first) who chose it
   * stands; with every person on one mesh, that is the page's own user alone. */
  private fitMessages(): object[] {
    const people = this.capture.people;
    const choices = this.meshChoices();
    const messages: object[] = [this.withMesh({ type: 'fit' })];
    const fitted = new Set([this.people.meshOf(people.main, choices)]);
    for (const person of people.others) {
      const mesh = this.people.meshOf(person, choices);
      if (fitted.has(mesh)) continue;
      fitted.add(mesh);
      messages.push({ type: 'fit', person, ...(mesh === null ? {} : { mesh }) });
    }
    return messages;
  }

  private voiceQuery(): string {
    const query = new URLSearchParams({ client: this.socket.client });
    const mesh = this.people.meshOf(this.capture.people.main, this.meshChoices());
    if (mesh !== null) query.set('mesh', String(mesh));
    return query.toString();
  }

  private onRemoteSkeleton(m: SkeletonMessage): void {
    if (!m.client || m.client === this.socket.client) return;
    let figure = this.others.get(m.client);
    if (!figure) {
      figure = new SkeletonFigure(OTHER_COLOURS[this.others.size % OTHER_COLOURS.length]);
      this.others.set(m.client, figure);
      this.viewport.scene.add(figure.group);
    }
    figure.update(m.positions.map((p, j) => (m.tracked[j] ? p : null)));
    this.avatars.drive(m.positions, m.tracked, m.client, { hands: m.hands, face: faceScores(m.blendshapes) });
  }

  // --- capture ------------------------------------------------------------------------------------
  private onUser(frame: UserFrame | null): void {
    if (frame) {
      this.me.group.visible = true;
      this.me.update(frame.positions, this.preview?.attachableJoints ?? []);
      this.sendFrame(frame.positions, frame.tracked, frame.t, handsFaceFields(frame.hands, frame.face));
      this.avatars.drive(frame.positions, frame.tracked, 'me', frame);
    } else {
      // nobody in view: an all-untracked frame makes the server hold the last pose
      this.sendFrame(new Array(JOINT_COUNT).fill(null), new Array(JOINT_COUNT).fill(false), Date.now());
    }
  }

  private sendFrame(positions: (Vec3 | null)[], tracked: boolean[], t: number, extra: object = {}): void {
    this.socket.sendFrame({ type: 'skeleton', seq: ++this.seq, t, model: 'kinect20', positions, tracked, ...extra });
  }

  // --- voice ----------------------------------------------------------------------------------------
  private async toggleVoice(): Promise<void> {
    if (this.voice.listening) {
      this.voice.stop();
      this.panel.setActive('voice', false);
      return;
    }
    try {
      await this.voice.start();
      this.panel.setActive('voice', true);
      this.panel.setMessage('listening: say “possess”, “release”, or a body part like “left arm”');
    } catch (err) {
      this.panel.setMessage(`microphone: ${(err as Error).message}`, true);
    }
  }

  private onVoice(r: VoiceResult): void {
    this.lastVoice = r;
    if (r.error) this.panel.setMessage(`voice: ${r.error}`, true);
    else if (r.command) {
      if (r.command.subset) this.panel.subset = r.command.subset;
      if (r.command.verb === 'reset') this.physics.reset();
      this.panel.setMessage(`heard “${r.command.text}”`);
    }
  }

  // --- per rendered frame -------------------------------------------------------------------------
  private frame(): void {
    const now = performance.now();
    for (const [client, figure] of this.others) {
      if (now - figure.updatedAt > STALE_MS) { figure.dispose(); this.others.delete(client); }
    }
    const figures = [this.me, ...this.others.values()].filter((f) => f.group.visible);
    const segments = figures.flatMap((f) => f.segments());
    for (const view of this.views.values()) view.graph.setSkeletonSegments(segments);
    if (this.preview && now - this.previewClock > 100) {
      this.previewClock = now;
      this.placement.holder.updateMatrixWorld(true);
      const result = this.preview.update(figures.map((f) => f.positions), this.placement.holder.matrixWorld);
      figures.forEach((f, i) => f.update(f.positions, result[i]));
      this.me.updatedAt = now;
    }
    if (this.viewport.frames % 15 === 0) {
      this.wantHandsAndFace();
      this.updateStatus();
      this.people.show(this.capture.people.ids, this.capture.people.main, this.meshChoices());
    }
  }

  /** The tracker looks for hands and a face only while an avatar, the face puppet or a hand puppet uses them. */
  private wantHandsAndFace(): void {
    const avatar = this.avatars.payload !== null;
    this.capture.want(avatar || this.puppet.hand !== null, avatar || this.face.on);
  }

  /** Possess with every person in this camera: the page's own user first, then the others in id order (a
   * joint map gives them its sources in that order), by their bodies or the hand the panel chose. */
  possess(): void {
    const { subset } = this.panel, hand = this.puppet.hand;
    [possessMessage(subset, hand), ...this.capture.people.possessMessages(subset, hand)]
      .forEach((m) => this.socket.send(this.withMesh(m))); // each person's chosen mesh
  }

  get possessing(): boolean {
    return Boolean(this.state?.users.find((u) => u.client === this.socket.client)?.possessing);
  }

  sampleUser(): boolean {
    return Boolean(this.state?.users.find((u) => u.client === 'sample')?.possessing);
  }

  /** "scene lost" / "scene is back" once per change; true when the state carries no scene to show. */
  private sceneLostNotice(m: SceneState): boolean {
    if (Boolean(m.scene_lost) !== this.sceneLost) {
      this.sceneLost = Boolean(m.scene_lost);
      this.panel.setMessage(this.sceneLost ? 'scene lost: the scene process stopped answering; waiting for it…'
        : 'the scene is back', this.sceneLost);
      this.updateStatus();
    }
    return m.meshes.length === 0;
  }

  private updateStatus(): void {
    this.panel.setStatus(statusLine({
      connected: this.connected, client: this.socket.client, refused: this.socket.refused, sceneLost: this.sceneLost,
      state: this.state, camera: this.camera.running, trackingLost: this.capture.trackingLost,
      trackedJoints: this.capture.trackedJoints, fps: this.viewport.fps,
    }));
  }
}
