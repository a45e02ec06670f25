// The people in this page's camera, one row each, with the mesh each one possesses: a scene can hold several
// meshes, and "possess" (the button, P, or the voice command) gives every person the mesh chosen here.
export interface MeshChoice {
  id: number;
  name: string;
}

export class PeopleList {
  readonly root: HTMLElement;
  /** Person id → the mesh id chosen for them (absent: the scene's first mesh). */
  readonly choice = new Map<number, number>();
  private shown = '';

  constructor(area: HTMLElement) {
    this.root = document.createElement('div');
    this.root.id = 'people';
    this.root.hidden = true;
    area.appendChild(this.root);
  }

  /** The mesh chosen for `person`, if that mesh is still in the scene (else null: the first mesh). */
  meshOf(person: number | null, meshes: MeshChoice[]): number | null {
    const chosen = person === null ? undefined : this.choice.get(person);
    return chosen !== undefined && meshes.some((m) => m.id === chosen) ? chosen : null;
  }

  /** One row per person in view (`main`: the page's own user); shown only when there is a mesh to choose. */
  show(people: number[], main: number | null, meshes: MeshChoice[]): void {
    const key = JSON.stringify([people, main, meshes]);
    if (key === this.shown) return; // rebuilt only on a change: an open selector stays open
    this.shown = key;
    this.root.hidden = meshes.length < 2 || people.length === 0;
    this.root.replaceChildren(...people.map((id) => {
      const row = document.createElement('div');
      row.className = 'row person';
      const label = document.createElement('span');
      label.textContent = id === main ? `you (person ${id})` : `person ${id}`;
      const select = document.createElement('select');
      select.dataset.person = String(id);
      select.title = 'the mesh this person possesses';
      for (const m of meshes) select.add(new Option(`${m.name} (${m.id})`, String(m.id)));
      select.value = String(this.meshOf(id, meshes) ?? meshes[0]?.id ?? '');
      select.addEventListener('change', () => {
        this.choice.set(id, Number(select.value));
        select.blur(); // give the keyboard shortcuts back
      });
      row.append(label, select);
      return row;
    }));
  }
}
