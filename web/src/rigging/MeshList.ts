// The scene's meshes, listed in the scene area while there are two or more: each with who possesses it, a
// choice that selects it (the gizmo, the up axis and the rigging preview then work on it) and a button that
// removes it from the scene (its possessors let go; the server keeps at least one mesh).
import type { MeshState } from '../net/protocol';

export class MeshList {
  readonly root: HTMLElement;
  private shown = '';

  constructor(area: HTMLElement, private readonly say: (text: string, error?: boolean) => void,
              private readonly select: (id: number) => void) {
    this.root = document.createElement('div');
    this.root.id = 'mesh-list';
    this.root.hidden = true;
    area.appendChild(this.root);
  }

  /** List `meshes` with `selected` checked. */
  show(meshes: MeshState[], selected: number | null): void {
    const key = JSON.stringify([selected, meshes.map((m) => [m.id, m.name, m.possessors])]);
    if (key === this.shown) return;
    this.shown = key;
    this.root.hidden = meshes.length < 2;
    this.root.replaceChildren(...meshes.map((m) => {
      const row = document.createElement('div');
      row.className = 'row';
      const label = document.createElement('label');
      const pick = document.createElement('input');
      pick.type = 'radio';
      pick.name = 'mesh-selected';
      pick.dataset.mesh = String(m.id);
      pick.checked = m.id === selected;
      pick.title = 'select this mesh: the gizmo moves it, the up axis and the rigging preview are its';
      pick.addEventListener('change', () => { if (pick.checked) this.select(m.id); pick.blur(); });
      const who = m.possessors.length ? `driven by ${m.possessors.join(' + ')}` : 'at rest';
      label.append(pick, ` ${m.name} (${m.id}): ${who}`);
      const remove = document.createElement('button');
      remove.textContent = 'Remove';
      remove.dataset.mesh = String(m.id);
      remove.title = 'remove this mesh from the scene (its possessors let go)';
      remove.addEventListener('click', () => void this.remove(m.id));
      row.append(label, remove);
      return row;
    }));
  }

  private async remove(id: number): Promise<void> {
    const r = await fetch(`api/mesh/${id}`, { method: 'DELETE' });
    const reply = (await r.json()) as { error?: string };
    if (!r.ok) this.say(reply.error ?? `remove mesh ${id}: HTTP ${r.status}`, true);
    else this.say(`mesh ${id} removed`);
  }
}
