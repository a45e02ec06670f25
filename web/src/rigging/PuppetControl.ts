// Possession by a hand (a hand puppet): "Possess with" picks the body or the user's tracked left or right hand.
// With a hand, the server takes the hand's 21 landmarks (sent with every skeleton frame) as a skeleton of its
// own, fits it into the mesh from the two shapes with its fingers as the mesh's legs, and the hand drives the
// mesh instead of the body (docs/tracking.md). `?puppet=left` or `?puppet=right` in the page's address
// starts with that hand chosen.

export type PuppetHand = 'left' | 'right' | null;

const CHOICES: [string, PuppetHand][] = [['body', null], ['left hand', 'left'], ['right hand', 'right']];

/** The hand named by the page's address (`?puppet=left|right`), or null for the body. */
export function puppetFromQuery(query: URLSearchParams): PuppetHand {
  const value = query.get('puppet');
  return value === 'left' || value === 'right' ? value : null;
}

export class PuppetControl {
  readonly select: HTMLSelectElement;

  constructor(row: HTMLElement, initial: PuppetHand, onChange: (hand: PuppetHand) => void) {
    this.select = document.createElement('select');
    this.select.id = 'puppet';
    this.select.title = 'what possesses the mesh: your body, or one hand (its fingers as the mesh’s legs)';
    for (const [label, hand] of CHOICES) this.select.add(new Option(`with ${label}`, hand ?? 'body'));
    this.hand = initial;
    this.select.addEventListener('change', () => {
      onChange(this.hand);
      this.select.blur(); // give the keyboard shortcuts back
    });
    row.appendChild(this.select);
  }

  get hand(): PuppetHand {
    const value = this.select.value;
    return value === 'left' || value === 'right' ? value : null;
  }

  set hand(hand: PuppetHand) {
    this.select.value = hand ?? 'body';
  }
}

/** A possess message for the page's own user (no `person`) or one of the other people in its camera: by the
 * body with `subset`, or by one hand. */
export function possessMessage(subset: string | null, hand: PuppetHand, person?: number): object {
  return { type: 'possess', subset: hand ? null : subset, ...(hand ? { hand } : {}),
    ...(person === undefined ? {} : { person }) };
}
