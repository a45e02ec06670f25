// window.kinetre: a small read-only view of the page for browser tests and for the curious in devtools.
import type { Studio } from '../app/Studio';

export function installTestHook(studio: Studio): void {
  const sampleIndices = (count: number, total: number) =>
    Array.from({ length: Math.min(count, total) }, (_, i) => Math.floor((i * total) / Math.min(count, total)));
  (window as unknown as { kinetre: object }).kinetre = {
    studio,
    state() {
      const mesh = studio.graphMesh;
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
        trackingLost: studio.capture.trackingLost,
        framesSent: studio.socket.sentFrames,
        possessing: studio.possessing,
        attachableJoints: studio.preview?.attachableJoints.filter(Boolean).length ?? 0,
        users: studio.state?.users ?? [],
        placement: studio.state?.placement ?? null,
        recording: studio.state?.recording ?? false,
        vertices: mesh ? mesh.skinnedPositions(sampleIndices(64, vertexCount)) : [],
        skeleton: studio.me.positions,
        fps: studio.viewport.fps,
        renderMs: studio.viewport.renderMs,
        updateMs: studio.viewport.updateMs,
        detectMs: studio.capture.tracker.detectMs,
        detections: studio.capture.tracker.detections,
        delegate: studio.capture.tracker.delegate,
        people: studio.capture.people,
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
