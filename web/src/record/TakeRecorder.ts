// Record a take on the server (every solved frame) and offer its exports, each mesh's alike: GLB (the mesh
// animated), BVH and the skeleton stream (.kinetre.jsonl).

/** One mesh that moved during the take, with its files (take-mesh<id>.*). */
export interface TakeMeshFiles {
  id: number;
  name: string;
  frames: number;
  files: Record<string, string>; // kind ("glb", "transforms", "bvh", "stream") → URL
}

export interface TakeFiles {
  take: number;
  frames: number;
  fps: number;
  files: Record<string, string>; // "kind-id" → URL, every mesh's
  meshes: TakeMeshFiles[];
}

export class TakeRecorder {
  recording = false;
  last: TakeFiles | null = null;

  async start(): Promise<void> {
    const r = await fetch('api/record/start', { method: 'POST' });
    if (!r.ok) throw new Error(`cannot start recording (HTTP ${r.status})`);
    this.recording = true;
  }

  async stop(): Promise<TakeFiles> {
    this.recording = false;
    const r = await fetch('api/record/stop', { method: 'POST' });
    const body = (await r.json()) as TakeFiles & { error?: string };
    if (!r.ok) throw new Error(body.error ?? `cannot stop recording (HTTP ${r.status})`);
    this.last = body;
    return body;
  }
}
