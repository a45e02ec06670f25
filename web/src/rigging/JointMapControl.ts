// The joint map entry of the panel: upload a JSON joint map (docs/joint-maps.md) so that, when several users
// possess one mesh, the n-th to possess drives with the joints the map's n-th source keeps (two people as
// the front and back legs of a horse); "Clear" removes it. The server checks the file and says what is wrong.

export interface JointMapState {
  name: string;
  sources: number;
}

export class JointMapControl {
  readonly row: HTMLElement;
  private readonly label: HTMLElement;
  private readonly clear: HTMLButtonElement;

  constructor(area: HTMLElement, private readonly say: (text: string, error?: boolean) => void) {
    this.row = document.createElement('div');
    this.row.className = 'row';
    this.row.id = 'joint-map-row';
    this.row.innerHTML = `
      <label class="file" title="a JSON joint map: which joints each possessing user drives with">Joint map… <input type="file" id="joint-map" accept=".json,application/json"></label>
      <button id="joint-map-clear" hidden>Clear</button>
      <span id="joint-map-name" class="hint"></span>`;
    area.appendChild(this.row);
    const input = this.row.querySelector('#joint-map') as HTMLInputElement;
    this.label = this.row.querySelector('#joint-map-name') as HTMLElement;
    this.clear = this.row.querySelector('#joint-map-clear') as HTMLButtonElement;
    input.addEventListener('change', () => {
      const file = input.files?.[0];
      input.value = '';
      if (file) void this.upload(file);
    });
    this.clear.addEventListener('click', () => void this.send('DELETE', 'api/jointmap'));
  }

  async upload(file: File): Promise<void> {
    await this.send('POST', `api/jointmap?name=${encodeURIComponent(file.name)}`, await file.text());
  }

  /** Show the map the server holds (from every state message). */
  show(map: JointMapState | null | undefined): void {
    this.label.textContent = map ? `${map.name}: ${map.sources} source${map.sources === 1 ? '' : 's'}` : '';
    this.clear.hidden = !map;
  }

  private async send(method: string, url: string, body?: string): Promise<void> {
    try {
      const r = await fetch(url, { method, body, headers: body ? { 'Content-Type': 'application/json' } : {} });
      const reply = await r.json();
      if (!r.ok) throw new Error(reply.error ?? `joint map: HTTP ${r.status}`);
      this.show(reply.joint_map);
      this.say(reply.joint_map
        ? `joint map ${reply.joint_map.name}: the next users to possess drive with its sources' joints, in turn`
        : 'joint map cleared: everybody drives with their own subset');
    } catch (err) {
      this.say((err as Error).message, true);
    }
  }
}
