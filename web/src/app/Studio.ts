// The page's wiring along the data path: this page's capture (CaptureLoop) → its skeleton channel on the
// socket → the server's node transforms → the mesh skinned on the GPU, with the other users' skeletons,
// the rigging view, an avatar, a face, physics (Playground), voice, and takes (TakeSession).
import { Camera } from '../capture/Camera';
import { FaceController, installFaceTestHook } from '../face/FaceController';
import { neckAnchor } from '../face/neckAnchor';
import { JOINT_COUNT } from '../capture/kinect20';
import { faceScores, handsFaceFields } from '../net/handsFace';
import type { SceneState, ServerMessage, SkeletonMessage, TransformBlock, Vec3 } from '../net/protocol';
import { StudioSocket } from '../net/StudioSocket';
import { AvatarStage } from '../avatar/AvatarStage';
import { Playground } from '../physics/Playground';
import { AttachPreview } from '../rigging/AttachPreview';
import { MeshUploader } from '../rigging/MeshUploader';
import { PlacementControls } from '../rigging/PlacementControls';
import { fetchMesh } from '../scene/MeshPayload';
import { SkeletonFigure } from '../scene/SkeletonFigure';
import { SkinnedGraphMesh } from '../scene/SkinnedGraphMesh';
import { Viewport } from '../scene/Viewport';
import { Panel } from '../ui/Panel';
import { JointMapControl } from '../rigging/JointMapControl';
import { PuppetControl, possessMessage, puppetFromQuery } from '../rigging/PuppetControl';
import { UpAxisControl } from '../rigging/UpAxisControl';
import { VoiceListener, type VoiceResult } from '../voice/VoiceListener';
import { CaptureLoop, type UserFrame } from './CaptureLoop';
import { statusLine } from './StatusLine';
import { TakeSession } from './TakeSession';

const OTHER_COLOURS = [0x7fdbff, 0xb10dc9, 0x2ecc40, 0xffdc00];
const MY_COLOUR = 0xffffff;
const STALE_MS = 2000; // a remote skeleton not updated for this long disappears

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
  readonly puppet: PuppetControl;
  readonly upAxis: UpAxisControl;
  readonly avatars: AvatarStage;
  readonly physics: Playground;
  readonly face: FaceController;
  graphMesh: SkinnedGraphMesh | null = null;
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
  private loadingMesh = 0;
  private pending: TransformBlock | null = null;
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
      fit: () => this.socket.send({ type: 'fit' }),
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
    this.placement = new PlacementControls(this.viewport.camera, this.viewport.renderer.domElement,
      this.viewport.controls, this.viewport.scene, (m) => this.socket.send(m));
    this.voice = new VoiceListener(() => this.socket.client, (r) => this.onVoice(r));
    this.takes = new TakeSession(this.viewport.renderer.domElement, {
      say,
      downloads: (links) => this.panel.setDownloads(links),
      companion: this.avatars,
      recorded: (url, fps) => { if (this.state) this.physics.setTake(url, fps, this.state.placement.matrix); },
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
    this.uploader.bind(root, this.panel.fileInput);
    this.jointMap = new JointMapControl(this.panel.area('body'), say);
    // a hand chosen while possessing takes over from the body (or the other hand) at once
    this.puppet = new PuppetControl(this.panel.area('body').querySelector('#body-drive') as HTMLElement,
      puppetFromQuery(new URLSearchParams(location.search)), () => { if (this.possessing) this.possess(); });
    this.upAxis = new UpAxisControl(this.panel.area('scene'), say);

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
      meshMatrix: () => {
        this.placement.holder.updateMatrixWorld(true);
        return this.placement.holder.matrixWorld.elements;
      },
      liveMesh: () => this.graphMesh,
      say,
      progress: (label, fraction) => this.panel.setProgress(label, fraction),
    });
    this.face = new FaceController(this.camera, this.viewport, this.panel.area('face'), say);
    this.face.anchor = () => neckAnchor((joint) => this.avatars.bone(joint));  // on an avatar's neck, if any
    installFaceTestHook(this.face);
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
        this.placement.apply(m.placement);
        if (!this.graphMesh || this.graphMesh.data.id !== m.mesh.id) void this.loadMesh(m.mesh.id, m.mesh.url);
        this.panel.setActive('sample', this.sampleUser(), undefined);
        this.panel.setActive('possess', this.possessing);
        this.panel.setActive('record', m.recording);
        this.jointMap.show(m.joint_map);
        this.upAxis.show(m.mesh.up, m.mesh.up_reason);
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

  private onTransforms(block: TransformBlock): void {
    this.transformsSeen++;
    if (!this.graphMesh || block.meshId !== this.graphMesh.data.id) {
      this.pending = block; // the mesh is still loading: apply when it arrives
      return;
    }
    this.physics.setTransforms(block.rows);
    if (this.physics.replaying) return; // the replay draws the take's poses
    this.graphMesh.setNodeMatrices(block.rows, block.seq);
    if (block.tSource > 0) this.latency = [...this.latency.slice(-59), Date.now() - block.tSource];
  }

  private async loadMesh(id: number, url: string): Promise<void> {
    if (this.loadingMesh === id) return;
    this.loadingMesh = id;
    const data = await fetchMesh(url.replace(/^\//, ''));
    if (this.state && this.state.mesh.id !== id) return; // replaced while downloading
    this.graphMesh?.mesh.removeFromParent();
    this.graphMesh?.dispose();
    this.preview?.dispose();
    this.graphMesh = new SkinnedGraphMesh(data);
    this.preview = new AttachPreview(data.nodes);
    this.placement.holder.add(this.graphMesh.mesh, this.preview.points);
    if (this.pending && this.pending.meshId === id) this.graphMesh.setNodeMatrices(this.pending.rows, this.pending.seq);
    this.physics.setMesh(data);
    if (this.pending && this.pending.meshId === id) this.physics.setTransforms(this.pending.rows);
    this.pending = null;
    this.updateStatus();
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
    this.graphMesh?.setSkeletonSegments(figures.flatMap((f) => f.segments()));
    if (this.preview && now - this.previewClock > 100) {
      this.previewClock = now;
      this.placement.holder.updateMatrixWorld(true);
      const result = this.preview.update(figures.map((f) => f.positions), this.placement.holder.matrixWorld);
      figures.forEach((f, i) => f.update(f.positions, result[i]));
      this.me.updatedAt = now;
    }
    if (this.viewport.frames % 15 === 0) this.updateStatus();
  }

  /** Possess with every person in this camera: the page's own user first, then the others in id order (a
   * joint map gives them its sources in that order), by their bodies or the hand the panel chose. */
  possess(): void {
    const { subset } = this.panel, hand = this.puppet.hand;
    [possessMessage(subset, hand), ...this.capture.people.possessMessages(subset, hand)].forEach((m) => this.socket.send(m));
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
    return !m.mesh;
  }

  private updateStatus(): void {
    this.panel.setStatus(statusLine({
      connected: this.connected, client: this.socket.client, refused: this.socket.refused, sceneLost: this.sceneLost,
      state: this.state, camera: this.camera.running, trackingLost: this.capture.trackingLost,
      trackedJoints: this.capture.trackedJoints, fps: this.viewport.fps,
    }));
  }
}
