// Stable ids for the people MediaPipe finds in each frame: detections are assigned to tracks by the
// assignment of least total torso-centre distance (exact, by enumeration: at most a handful of people), a
// track unseen for less than MEMORY_MS waits for its person to come back, and the distance a returning
// person may have moved grows with the time they were gone.
import type { PoseLandmarks } from './detection';
import { distinct, pixels } from './tiles';

const MEMORY_MS = 10000; // the landmarker may lose one of several people for seconds while it tracks the others
const GATE = 0.15; // image widths a person may move between two frames
const GATE_PER_SECOND = 0.15; // … plus this much per second unseen
const AGE_COST = 0.05; // image widths a track's cost grows per second unseen: the person's current track
// wins over an older one left nearby (a jump that opened a new track must not flip between the two)
const TORSO = [11, 12, 23, 24];

export interface Track {
  id: number;
  centre: [number, number]; // torso centre, in image widths
  lastSeen: number; // ms
  firstSeen: number; // ms
}

export function torsoCentre(pose: PoseLandmarks, aspect: number): [number, number] {
  let x = 0, y = 0;
  for (const i of TORSO) {
    x += pose.image[i].x / TORSO.length;
    y += pose.image[i].y / TORSO.length / aspect;
  }
  return [x, y];
}

/** The poses that are distinct people: the landmarker can report one person twice, as two overlapping poses
 * (`distinct`: the median landmark distance under a quarter of the body's size). The first of such a pair is
 * kept. */
export function distinctPoses(poses: PoseLandmarks[], aspect: number): PoseLandmarks[] {
  return distinct(poses.map((p) => pixels(p.image, aspect, 1)), poses.map(() => 0)).map((i) => poses[i]);
}

/** The injective assignment rows → columns (or -1) of least total cost among the allowed pairs, favouring
 * more pairs first: cost[r][c] is Infinity where a pair is not allowed. */
export function assign(cost: number[][]): number[] {
  const rows = cost.length, cols = rows ? cost[0].length : 0;
  let best: number[] = new Array(rows).fill(-1);
  let bestPairs = 0, bestCost = 0;
  const used = new Array(cols).fill(false);
  const current: number[] = [];
  const walk = (r: number, pairs: number, total: number) => {
    if (r === rows) {
      if (pairs > bestPairs || (pairs === bestPairs && total < bestCost)) {
        best = [...current]; bestPairs = pairs; bestCost = total;
      }
      return;
    }
    for (let c = 0; c < cols; c++) {
      if (used[c] || !Number.isFinite(cost[r][c])) continue;
      used[c] = true; current.push(c);
      walk(r + 1, pairs + 1, total + cost[r][c]);
      used[c] = false; current.pop();
    }
    current.push(-1);
    walk(r + 1, pairs, total);
    current.pop();
  };
  walk(0, 0, 0);
  return best;
}

export class PersonTracks {
  private tracks: Track[] = [];
  private nextId = 1;

  /** The id of each pose, in the order given; new people get new ids. */
  update(poses: PoseLandmarks[], aspect: number, now: number): number[] {
    this.tracks = this.tracks.filter((t) => now - t.lastSeen <= MEMORY_MS);
    const centres = poses.map((p) => torsoCentre(p, aspect));
    const cost = centres.map((c) => this.tracks.map((t) => {
      const d = Math.hypot(c[0] - t.centre[0], c[1] - t.centre[1]);
      const unseen = (now - t.lastSeen) / 1000;
      return d <= GATE + GATE_PER_SECOND * unseen ? d + AGE_COST * unseen : Infinity;
    }));
    const match = assign(cost);
    return centres.map((centre, i) => {
      let track = match[i] >= 0 ? this.tracks[match[i]] : undefined;
      if (!track) {
        track = { id: this.nextId++, centre, lastSeen: now, firstSeen: now };
        this.tracks.push(track);
      }
      track.centre = centre;
      track.lastSeen = now;
      return track.id;
    });
  }

  /** Ids remembered (seen within the memory), oldest first. */
  get ids(): number[] {
    return this.tracks.map((t) => t.id);
  }

  /** The people remembered, as of the last update. */
  get remembered(): readonly Readonly<Track>[] {
    return this.tracks;
  }

  forget(): void {
    this.tracks = [];
  }
}
