// The "Motion…" entry of the scene area: a motion file (BVH, glTF/GLB, VRM Animation .vrma, a Kinetre take)
// posted to the server, which plays it in a loop as the sample motion and possesses the mesh with it.
// The server reads the file and says what is wrong with it.

/** The motion files the server plays (studio/player.py PLAYABLE). */
export const MOTION_EXTENSIONS = ['.bvh', '.vrma', '.glb', '.gltf', '.kinetre.jsonl'];

export interface MotionPlayed {
  motion: string;
  frames: number;
  fps: number;
}

export class MotionFileControl {
  readonly input: HTMLInputElement;

  constructor(area: HTMLElement, private readonly say: (text: string, error?: boolean) => void) {
    const row = document.createElement('div');
    row.className = 'row';
    row.innerHTML = `<label class="file" title="play a motion file (BVH, glTF, VRM Animation) as the sample motion">Motion… <input type="file" id="motion-file" accept="${MOTION_EXTENSIONS.join(',')}"></label>`;
    area.appendChild(row);
    this.input = row.querySelector('#motion-file') as HTMLInputElement;
    this.input.addEventListener('change', () => {
      const file = this.input.files?.[0];
      this.input.value = '';
      if (file) void this.upload(file);
    });
  }

  async upload(file: File): Promise<MotionPlayed | null> {
    this.say(`${file.name}: reading the motion…`);
    try {
      const r = await fetch(`api/motion?name=${encodeURIComponent(file.name)}`, { method: 'POST', body: file });
      const reply = await r.json();
      if (!r.ok) throw new Error(reply.error ?? `${file.name}: HTTP ${r.status}`);
      const played = reply as MotionPlayed;
      this.say(`${played.motion}: ${played.frames} frames at ${played.fps} fps play as the sample motion`);
      return played;
    } catch (err) {
      this.say((err as Error).message, true);
      return null;
    }
  }
}
