// window.kinetre: a small read-only view of the page for browser tests and for the curious in devtools.
import * as THREE from 'three';
import type { Studio } from '../app/Studio';
import type { SkinnedGraphMesh } from '../scene/SkinnedGraphMesh';

/** World-space [min, max] of the mesh as shown: its skinned vertices (up to 2048 of them, evenly spread)
 * through the placement. */
function meshBox(mesh: SkinnedGraphMesh): { min: number[]; max: number[] } {
  const count = mesh.data.positions.length / 3;
  const step = Math.max(1, Math.floor(count / 2048));
  const indices = Array.from({ length: Math.ceil(count / step) }, (_, i) => i * step);
  const box = new THREE.Box3();
  const v = new THREE.Vector3();
  for (const p of mesh.skinnedPositions(indices)) box.expandByPoint(v.set(p[0], p[1], p[2]));
  return { min: box.min.toArray(), max: box.max.toArray() };
}

export function installTestHook(studio: Studio): void {
  const sampleIndices = (count: number, total: number) =>
    Array.from({ length: Math.min(count, total) }, (_, i) => Math.floor((i * total) / Math.min(count, total)));
  (window as unknown as { kinetre: object }).kinetre = {
    studio,
    state() {
      const mesh = studio.selectedMesh; // the mesh selected in the mesh list (at first the first listed)
      const vertexCount = mesh ? mesh.data.positions.length / 3 : 0;
      const median = (a: number[]) => (a.length ? [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)] : null);
      return {
        connected: studio.connected,
        client: studio.socket.client,
        meshId: mesh?.data.id ?? null,
        meshName: mesh?.data.name ?? null,
        nodeCount: mesh?.nodeCount ?? 0,
        transformsSeq: mesh?.seq ?? 0,
        transformsSeen: studio.transformsSeen,
        cameraRunning: studio.camera.running,
        trackedJoints: studio.capture.trackedJoints,
        handsSeen: studio.capture.handsSeen,
        trackingLost: studio.capture.trackingLost,
        framesSent: studio.socket.sentFrames,
        possessing: studio.possessing,
        puppet: studio.puppet.hand,
        attachableJoints: studio.preview?.attachableJoints.filter(Boolean).length ?? 0,
        users: studio.state?.users ?? [],
        meshUp: studio.selectedState?.up ?? null,
        meshBox: mesh ? meshBox(mesh) : null,
        // every mesh of the scene, in its order: who possesses it, its box and sampled vertices as shown
        meshes: (studio.state?.meshes ?? []).map((m) => {
          const shown = studio.views.get(m.id)?.graph ?? null;
          const count = shown ? shown.data.positions.length / 3 : 0;
          return { id: m.id, name: m.name, possessors: m.possessors, loaded: shown !== null,
            meshBox: shown ? meshBox(shown) : null, transformsSeq: shown?.seq ?? 0,
            vertices: shown ? shown.skinnedPositions(sampleIndices(64, count)) : [] };
        }),
        placement: studio.selectedState?.placement ?? null,
        recording: studio.state?.recording ?? false,
        vertices: mesh ? mesh.skinnedPositions(sampleIndices(64, vertexCount)) : [],
        skeleton: studio.me.positions,
        fps: studio.viewport.fps,
        renderMs: studio.viewport.renderMs,
        updateMs: studio.viewport.updateMs,
        detectMs: studio.capture.tracker.detectMs,
        detections: studio.capture.tracker.detections,
        delegate: studio.capture.tracker.delegate,
        people: studio.capture.people.ids,
        mainPerson: studio.capture.people.main,
        // each person in view: the server user it is, whether that user possesses, its tracked joints
        personUsers: studio.capture.people.ids.map((id) => {
          const user = studio.capture.people.user(studio.socket.client, id);
          const u = studio.state?.users.find((x) => x.client === user);
          return { id, user, possessing: Boolean(u?.possessing), mesh: u?.mesh ?? null, subset: u?.subset ?? null,
            attached: u?.attached.length ?? 0,
            tracked: studio.capture.people.frames.get(id)?.tracked.filter(Boolean).length ?? 0 };
        }),
        latencyMs: median(studio.latency),
        message: studio.panel.messageText,
        voice: studio.lastVoice,
        voiceUtterances: studio.voice.utterances,
        take: studio.takes.last,
        avatar: studio.avatars.state(),
        physics: studio.physics.state(),
      };
    },
  };
}
