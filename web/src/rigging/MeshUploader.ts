// Load a mesh by drag and drop or the file picker: upload (progress from the browser), then poll the
// server's preprocessing job (progress from the server) until the new mesh is ready or fails readably. A
// mesh replaces the scene's first mesh, or (the "Add mesh" picker) joins the scene beside the others.

export const MESH_EXTENSIONS = ['.obj', '.ply', '.stl', '.glb', '.gltf', '.off'];
// Rigged avatars (also offered to `intercept` first, which may take any skinned glTF).
export const AVATAR_ONLY_EXTENSIONS = ['.vrm'];
// A zip of RGB-D frames (TUM or Redwood layout) is the "Scan" entry: the server fuses it into a mesh first.
export const SCAN_EXTENSIONS = ['.zip'];

export interface UploadEvents {
  onProgress(label: string, fraction: number): void;
  onDone(meshId: number): void;
  onError(message: string): void;
}

export class MeshUploader {
  busy = false;

  /** `intercept` sees each file first and returns true when it took it (a skinned humanoid avatar). */
  constructor(private readonly events: UploadEvents,
    private readonly intercept?: (file: File) => Promise<boolean>) {}

  /** Make `target` accept dropped files and `input` pick them; `add` picks meshes added beside the others. */
  bind(target: HTMLElement, input: HTMLInputElement, add?: HTMLInputElement): void {
    target.addEventListener('dragover', (e) => { e.preventDefault(); target.classList.add('drop'); });
    target.addEventListener('dragleave', () => target.classList.remove('drop'));
    target.addEventListener('drop', (e) => {
      e.preventDefault();
      target.classList.remove('drop');
      const file = e.dataTransfer?.files[0];
      if (file) void this.upload(file);
    });
    input.accept = [...MESH_EXTENSIONS, ...AVATAR_ONLY_EXTENSIONS, ...SCAN_EXTENSIONS].join(',');
    input.addEventListener('change', () => {
      const file = input.files?.[0];
      if (file) void this.upload(file);
      input.value = '';
    });
    if (!add) return;
    add.accept = [...MESH_EXTENSIONS, ...SCAN_EXTENSIONS].join(',');
    add.addEventListener('change', () => {
      const file = add.files?.[0];
      if (file) void this.upload(file, true);
      add.value = '';
    });
  }

  async upload(file: File, add = false): Promise<void> {
    if (this.busy) return this.events.onError('a mesh is already being prepared');
    const ext = file.name.slice(file.name.lastIndexOf('.')).toLowerCase();
    if (!MESH_EXTENSIONS.includes(ext) && !SCAN_EXTENSIONS.includes(ext) && !AVATAR_ONLY_EXTENSIONS.includes(ext)
      && !file.name.toLowerCase().endsWith('.gz')) {
      return this.events.onError(
        `${file.name}: not a mesh file (expected ${MESH_EXTENSIONS.join(', ')}, or a .zip of RGB-D frames to scan)`);
    }
    this.busy = true;
    try {
      if (!add && this.intercept && (await this.intercept(file))) return;
      const job = await this.send(file, add);
      await this.follow(job);
    } catch (err) {
      this.events.onError((err as Error).message);
    } finally {
      this.busy = false;
    }
  }

  private send(file: File, add: boolean): Promise<number> {
    return new Promise((resolve, reject) => {
      const xhr = new XMLHttpRequest();
      xhr.open('POST', `api/mesh?name=${encodeURIComponent(file.name)}${add ? '&add=1' : ''}`);
      xhr.upload.onprogress = (e) => {
        if (e.lengthComputable) this.events.onProgress(`uploading ${file.name}`, 0.3 * (e.loaded / e.total));
      };
      xhr.onload = () => {
        const body = JSON.parse(xhr.responseText || '{}') as { job?: number; error?: string };
        if (xhr.status === 202 && body.job !== undefined) resolve(body.job);
        else reject(new Error(body.error ?? `${file.name}: upload failed (HTTP ${xhr.status})`));
      };
      xhr.onerror = () => reject(new Error(`${file.name}: upload failed (network)`));
      xhr.send(file);
    });
  }

  private async follow(job: number): Promise<void> {
    for (;;) {
      const r = await fetch(`api/jobs/${job}`);
      const s = (await r.json()) as { stage: string; fraction: number; error: string; done: boolean; mesh: number | null };
      if (s.error) throw new Error(s.error);
      this.events.onProgress(s.stage, 0.3 + 0.7 * s.fraction);
      if (s.done && s.mesh !== null) return this.events.onDone(s.mesh);
      await new Promise((res) => setTimeout(res, 200));
    }
  }
}
