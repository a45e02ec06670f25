// The status line at the top of the panel: the connection, the scene (mesh, who drives it, solve time),
// this page's tracking and its frame rate, in one line of parts.
import type { SceneState } from '../net/protocol';
import { qualityMeter } from './QualityMeter';

export interface StatusFacts {
  connected: boolean;
  client: string;
  refused: string; // why the server refused the connection, or ''
  sceneLost: boolean;
  state: SceneState | null;
  camera: boolean;
  trackingLost: boolean;
  trackedJoints: number;
  fps: number;
}

export function statusLine(f: StatusFacts): string {
  const offline = f.refused ? `refused: ${f.refused}` : 'offline: reconnecting…';
  const parts = [f.connected ? `connected as ${f.client}` : offline];
  if (f.sceneLost) parts.push('scene lost');
  if (f.state) {
    const meshes = f.state.meshes;
    parts.push(meshes.length === 1 ? `${meshes[0].name} (${meshes[0].nodes} nodes)`
      : meshes.map((m) => m.name).join(' + '));
    const drivers = f.state.users.filter((u) => u.possessing)
      .map((u) => (u.client === f.client ? 'you' : u.client) + (u.hand ? ` (${u.hand} hand)` : ''));
    parts.push(drivers.length ? `driven by ${drivers.join(' + ')}` : 'nobody possesses the mesh');
    if (f.state.solve_ms !== null) parts.push(`solve ${f.state.solve_ms.toFixed(1)} ms`);
    for (const u of f.state.users) {  // each user's live motion meter
      const meter = qualityMeter(u.quality, u.cleaning);
      if (meter) parts.push(`${u.client === f.client ? 'your' : `${u.client}'s`} motion: ${meter}`);
    }
  }
  if (f.camera) parts.push(f.trackingLost ? 'tracking lost: holding the pose' : `tracking ${f.trackedJoints}/20`);
  if (Number.isFinite(f.fps) && f.fps > 0) parts.push(`${f.fps.toFixed(0)} fps`);  // no "Infinity" before two frames
  return parts.join(' · ');
}
