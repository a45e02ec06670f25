// The avatar's bone map by hand: one menu per Kinect-20 joint listing the avatar's joints. Saving posts the
// map to the server, which writes it as JSON next to the avatar (used from then on) and answers with the
// new retargeting plan.
import { KINECT20_JOINTS } from '../capture/kinect20';

const REQUIRED = new Set(['HipCenter', 'ShoulderCenter', 'ShoulderLeft', 'ElbowLeft', 'WristLeft', 'ShoulderRight',
  'ElbowRight', 'WristRight', 'HipLeft', 'KneeLeft', 'AnkleLeft', 'HipRight', 'KneeRight', 'AnkleRight']);

export class AvatarMapEditor {
  readonly root: HTMLElement;
  private readonly selects = new Map<string, HTMLSelectElement>();

  constructor(container: HTMLElement, joints: string[], map: Record<string, number>, missing: string[],
    private readonly onSave: (table: Record<string, string>) => void, onClose: () => void) {
    this.root = document.createElement('div');
    this.root.id = 'avatar-map';
    this.root.innerHTML = `<div class="title">Avatar map: which avatar joint plays each body joint
      ${missing.length ? `<br><span class="error">missing: ${missing.join(', ')}</span>` : ''}</div>
      <div class="grid"></div>
      <div class="row"><button id="avatar-map-save">Save map</button> <button id="avatar-map-close">Close</button></div>`;
    const grid = this.root.querySelector('.grid') as HTMLElement;
    const counts = new Map<string, number>();
    joints.forEach((n) => counts.set(n, (counts.get(n) ?? 0) + 1));
    for (const kj of KINECT20_JOINTS) {
      const label = document.createElement('label');
      label.textContent = kj + (REQUIRED.has(kj) ? ' *' : '');
      const select = document.createElement('select');
      select.name = kj;
      select.add(new Option('(none)', ''));
      joints.forEach((name, i) => select.add(new Option(name, counts.get(name) === 1 ? name : `#${i}`)));
      const current = map[kj];
      if (current !== undefined) select.selectedIndex = current + 1;
      if (missing.includes(kj)) select.classList.add('missing');
      label.appendChild(select);
      grid.appendChild(label);
      this.selects.set(kj, select);
    }
    (this.root.querySelector('#avatar-map-save') as HTMLButtonElement).addEventListener('click', () => this.onSave(this.table()));
    (this.root.querySelector('#avatar-map-close') as HTMLButtonElement).addEventListener('click', onClose);
    container.appendChild(this.root);
  }

  /** Kinect joint → avatar joint (name, or "#index" for an ambiguous name), unset joints left out. */
  table(): Record<string, string> {
    const out: Record<string, string> = {};
    for (const [kj, select] of this.selects) if (select.value) out[kj] = select.value;
    return out;
  }

  /** Choose an avatar joint for a Kinect joint (by index), as a user would in the menu. */
  choose(kinectJoint: string, jointIndex: number): void {
    const select = this.selects.get(kinectJoint);
    if (select) select.selectedIndex = jointIndex + 1;
  }

  dispose(): void {
    this.root.remove();
  }
}
