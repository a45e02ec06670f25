// The up-axis entry of the panel: the server stands each mesh upright on load (the stored axis it rests on
// best, mesh/upright.py); this shows which axis it chose and why, and one click stands the mesh on its +Z
// (from +Y) or its +Y (from any other axis) instead (the server turns it and rebuilds its graph, like an
// upload).

export class UpAxisControl {
  readonly row: HTMLElement;
  private readonly button: HTMLButtonElement;
  private readonly label: HTMLElement;
  private up = 'y';
  private mesh: number | null = null; // the mesh whose axis is shown (the selected one)
  busy = false;

  constructor(area: HTMLElement, private readonly say: (text: string, error?: boolean) => void) {
    this.row = document.createElement('div');
    this.row.className = 'row';
    this.row.id = 'up-axis-row';
    this.row.innerHTML = `
      <button id="up-axis" title="stand the mesh on the other axis: its file's +Y or +Z up">Stand on +Z</button>
      <span id="up-axis-reason" class="hint"></span>`;
    area.appendChild(this.row);
    this.button = this.row.querySelector('#up-axis') as HTMLButtonElement;
    this.label = this.row.querySelector('#up-axis-reason') as HTMLElement;
    this.button.addEventListener('click', () => void this.flip());
  }

  /** Show the axis the server stood mesh `mesh` on (the selected mesh, from every state message). */
  show(mesh: number, up: string | undefined, reason: string | undefined): void {
    this.mesh = mesh;
    this.up = up ?? 'y';
    this.button.textContent = this.up === 'y' ? 'Stand on +Z' : 'Stand on +Y';
    this.label.textContent = reason ?? '';
  }

  async flip(): Promise<void> {
    if (this.busy) return;
    this.busy = true;
    this.button.disabled = true;
    const up = this.up === 'y' ? 'z' : 'y';
    try {
      const r = await fetch(`api/mesh/up?up=${up}${this.mesh === null ? '' : `&mesh=${this.mesh}`}`, { method: 'POST' });
      const reply = await r.json();
      if (!r.ok) throw new Error(reply.error ?? `up axis: HTTP ${r.status}`);
      this.say(`standing the mesh with its +${up.toUpperCase()} up…`);
      for (;;) {
        const job = await (await fetch(`api/jobs/${reply.job}`)).json();
        if (job.error) throw new Error(job.error);
        if (job.done) break;
        await new Promise((resolve) => setTimeout(resolve, 250));
      }
      this.say(`the mesh stands with its +${up.toUpperCase()} up`);
    } catch (err) {
      this.say((err as Error).message, true);
    } finally {
      this.busy = false;
      this.button.disabled = false;
    }
  }
}
