// The control panel, in areas by what a person is doing: the scene (which mesh, where), the body (camera,
// voice, possession), an avatar, a face, physics, and recording. Modules put their controls in their area
// (`area(name)`), and an area shows only the controls in use: one whose controls are all hidden shows
// nothing, not even its heading (style.css). Buttons have keyboard shortcuts; status, progress and the
// message line stay on top of and below the areas.
import { SUBSETS } from '../capture/kinect20';

export interface PanelActions {
  camera(): void;
  voice(): void;
  sample(): void;
  possess(): void;
  release(): void;
  subset(name: string | null): void;
  fit(): void;
  mode(mode: 'translate' | 'rotate' | 'scale'): void;
  record(): void;
}

const KEYS: Record<string, keyof PanelActions | ['mode', 'translate' | 'rotate' | 'scale']> = {
  c: 'camera', v: 'voice', m: 'sample', p: 'possess', r: 'release', f: 'fit', ' ': 'record',
  w: ['mode', 'translate'], e: ['mode', 'rotate'], s: ['mode', 'scale'],
};

export type AreaName = 'scene' | 'body' | 'avatar' | 'face' | 'physics' | 'record';

export class Panel {
  readonly root: HTMLElement;
  readonly fileInput: HTMLInputElement;
  readonly addInput: HTMLInputElement; // a mesh added beside the others
  private readonly status: HTMLElement;
  private readonly message: HTMLElement;
  private readonly progress: HTMLProgressElement;
  private readonly progressLabel: HTMLElement;
  private readonly downloads: HTMLElement;
  private readonly subsetSelect: HTMLSelectElement;
  private readonly buttons = new Map<string, HTMLButtonElement>();
  messageText = '';

  constructor(container: HTMLElement, actions: PanelActions) {
    this.root = document.createElement('div');
    this.root.id = 'panel';
    this.root.innerHTML = `
      <h1>Kinetre studio</h1>
      <div id="status">connecting…</div>
      <section class="area" id="area-scene"><h2>Scene</h2>
        <div class="row">
          <label class="file" title="replaces the first mesh">Load mesh… <input type="file" id="file"></label>
          <label class="file" title="a mesh of its own for another person, beside the others">Add mesh… <input type="file" id="file-add"></label>
          <button id="sample" title="M">Sample motion</button>
        </div>
        <div class="row">
          <button id="fit" title="F: scale the mesh to your height and stand it where you stand">Fit to me</button>
          <button id="mode-translate" title="W">Move</button>
          <button id="mode-rotate" title="E">Rotate</button>
          <button id="mode-scale" title="S">Scale</button>
        </div>
      </section>
      <section class="area" id="area-body"><h2>Body</h2>
        <div class="row">
          <button id="camera" title="C">Camera</button>
          <button id="voice" title="V">Voice</button>
        </div>
        <div class="row" id="body-drive" hidden>
          <button id="possess" title="P or say “possess”">Possess</button>
          <button id="release" title="R or say “release”">Release</button>
          <select id="subset" title="which joints drive the mesh"></select>
        </div>
      </section>
      <section class="area" id="area-avatar"><h2>Avatar</h2></section>
      <section class="area" id="area-face"><h2>Face</h2></section>
      <section class="area" id="area-physics"><h2>Physics</h2></section>
      <section class="area" id="area-record"><h2>Record</h2>
        <div class="row"><button id="record" title="Space">Record</button></div>
        <div id="downloads" hidden></div>
      </section>
      <div id="progress-row" hidden><progress id="progress" max="1" value="0"></progress> <span id="progress-label"></span></div>
      <div id="downloads"></div>
      <div id="message" role="status"></div>
      <div class="hint">Drop an OBJ, PLY, STL or GLB anywhere on the page, or a .zip of RGB-D frames to scan an object (TUM or Redwood layout).</div>`;
    container.appendChild(this.root);
    const $ = <T extends HTMLElement>(id: string) => this.root.querySelector(`#${id}`) as T;
    this.status = $('status');
    this.message = $('message');
    this.progress = $<HTMLProgressElement>('progress');
    this.progressLabel = $('progress-label');
    this.downloads = $('downloads');
    this.fileInput = $<HTMLInputElement>('file');
    this.addInput = $<HTMLInputElement>('file-add');
    this.subsetSelect = $<HTMLSelectElement>('subset');
    for (const name of SUBSETS) this.subsetSelect.add(new Option(name, name));
    this.subsetSelect.addEventListener('change', () => {
      actions.subset(this.subset);
      this.subsetSelect.blur(); // give the keyboard shortcuts back
    });

    for (const id of ['camera', 'voice', 'sample', 'possess', 'release', 'fit', 'record'] as const) {
      const b = $<HTMLButtonElement>(id);
      this.buttons.set(id, b);
      b.addEventListener('click', () => actions[id]());
    }
    for (const mode of ['translate', 'rotate', 'scale'] as const) {
      $<HTMLButtonElement>(`mode-${mode}`).addEventListener('click', () => actions.mode(mode));
    }
    window.addEventListener('keydown', (e) => {
      if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement || e.repeat) return;
      const action = KEYS[e.key.toLowerCase()];
      if (!action) return;
      e.preventDefault();
      if (Array.isArray(action)) actions.mode(action[1]);
      else (actions[action] as () => void)();
    });
  }

  /** The panel area for one activity's controls. */
  area(name: AreaName): HTMLElement {
    return this.root.querySelector(`#area-${name}`) as HTMLElement;
  }

  /** Possession's controls, shown while this page's camera can give a body to possess with. */
  showDriving(shown: boolean): void {
    (this.root.querySelector('#body-drive') as HTMLElement).hidden = !shown;
  }

  get subset(): string | null {
    return this.subsetSelect.value === 'whole body' ? null : this.subsetSelect.value;
  }

  set subset(name: string | null) {
    this.subsetSelect.value = name ?? 'whole body';
  }

  setStatus(text: string): void {
    this.status.textContent = text;
  }

  setMessage(text: string, error = false): void {
    this.messageText = text;
    this.message.textContent = text;
    this.message.className = error ? 'error' : '';
  }

  setProgress(label: string | null, fraction = 0): void {
    (this.progress.parentElement as HTMLElement).hidden = label === null;
    this.progress.value = fraction;
    this.progressLabel.textContent = label ?? '';
  }

  setActive(id: string, active: boolean, label?: string): void {
    const b = this.buttons.get(id);
    if (!b) return;
    b.classList.toggle('active', active);
    if (label) b.textContent = label;
  }

  setDownloads(links: { label: string; href: string; file: string }[]): void {
    this.downloads.hidden = links.length === 0;
    this.downloads.replaceChildren(...links.map((l) => {
      const a = document.createElement('a');
      a.href = l.href;
      a.download = l.file;
      a.textContent = l.label;
      a.className = 'download';
      return a;
    }));
  }
}
