// The people in this page's camera as studio users: each tracked person (a stable id from PersonTracks) is
// mapped to Kinect 20 with a mapper of their own and sent on a channel of their own. One of them, the
// "main" person (`mainPerson`), drives the page's own channel (the user the page's buttons and voice talk
// about); every other person is sent with a "person" field and becomes the server user `<client>p<id>`.
// Possess and release apply to them all, so two people in one view can carry one horse through a joint map.
import type { Detection, PoseLandmarks } from '../capture/detection';
import { KinectMapper, type KinectFrame } from '../capture/KinectMapper';
import { PersonTracks, distinctPoses, torsoCentre, type Track } from '../capture/PersonTracks';
import { possessMessage, type PuppetHand } from '../rigging/PuppetControl';

export interface PersonFrame {
  id: number;
  main: boolean; // sent on the page's own channel
  frame: KinectFrame;
  pose: PoseLandmarks; // the landmarks it was mapped from
}

/** The person the page's own channel follows, after a detection's ids are assigned (`kinetre.motion.people.
 * main_person` keeps the same rule for `kinetre capture`). The main person keeps the role by id while
 * remembered, even unseen for a moment, so a second person never takes it over because the landmarker missed
 * the first in a frame or listed them in another order. It passes on when they are forgotten, or when someone
 * first seen after they were last seen is in view (the tracker gave the main person a new id after a jump):
 * to the one of those in view nearest the frame's `middle` (the lowest id on a tie); null when the main person
 * is forgotten and nobody is in view. `ids`, `centres`: this detection's people; `middle` in their units. */
export function mainPerson(main: number | null, remembered: readonly Readonly<Track>[], ids: number[],
  centres: [number, number][], middle: [number, number]): number | null {
  const known = new Map(remembered.map((t) => [t.id, t]));
  const kept = main === null ? undefined : known.get(main);
  const candidates = ids.map((id, i) => ({ id, i }))
    .filter(({ id }) => !kept || (id !== main && (known.get(id)?.firstSeen ?? -Infinity) > kept.lastSeen));
  if (kept && !candidates.length) return main;
  let best: number | null = null, nearest = Infinity;
  for (const { id, i } of candidates) {
    const d = Math.hypot(centres[i][0] - middle[0], centres[i][1] - middle[1]);
    if (d < nearest || (d === nearest && best !== null && id < best)) { best = id; nearest = d; }
  }
  return best;
}

export class People {
  readonly tracks = new PersonTracks();
  /** Ids in view in the newest detection, ascending. */
  ids: number[] = [];
  /** The person the page's own channel follows (`mainPerson`). */
  main: number | null = null;
  private readonly mappers = new Map<number, KinectMapper>();
  private readonly seqs = new Map<number, number>();
  /** The newest frame of each person in view. */
  readonly frames = new Map<number, KinectFrame>();

  constructor(private readonly sendFrame: (message: object) => void) {}

  /** Ids and Kinect frames of the people in `d`, in its order; the frames of all but the main one are sent. */
  update(d: Detection): PersonFrame[] {
    const poses = distinctPoses(d.poses, d.width / d.height);
    const aspect = d.width / d.height;
    const ids = this.tracks.update(poses, aspect, d.t);
    this.ids = [...ids].sort((a, b) => a - b);
    this.main = mainPerson(this.main, this.tracks.remembered, ids, poses.map((p) => torsoCentre(p, aspect)),
      [0.5, 0.5 / aspect]);
    for (const id of this.mappers.keys()) {
      if (!this.tracks.ids.includes(id)) { this.mappers.delete(id); this.frames.delete(id); }
    }
    const t = performance.timeOrigin + d.t; // the capture time, on the server's clock (ms since the epoch)
    const out: PersonFrame[] = [];
    poses.forEach((pose, i) => {
      const id = ids[i];
      let mapper = this.mappers.get(id);
      if (!mapper) { mapper = new KinectMapper(d.width / d.height); this.mappers.set(id, mapper); }
      const frame = mapper.map(pose.world, pose.image);
      this.frames.set(id, frame);
      const main = id === this.main;
      if (!main) {
        const seq = (this.seqs.get(id) ?? 0) + 1;
        this.seqs.set(id, seq);
        this.sendFrame({ type: 'skeleton', person: id, seq, t, model: 'kinect20', positions: frame.positions, tracked: frame.tracked });
      }
      out.push({ id, main, frame, pose });
    });
    for (const id of this.tracks.ids) if (!ids.includes(id)) this.frames.delete(id);
    return out;
  }

  /** The other people remembered (not the main one) who have a user `<client>p<id>`, ascending: one the
   * landmarker misses for a moment is still one of them. */
  get others(): number[] {
    return this.tracks.ids.filter((id) => id !== this.main && this.seqs.has(id)).sort((a, b) => a - b);
  }

  /** Possess after the page's own user: the others in id order (a joint map gives them its later sources), each
   * by the body with `subset` or by their `hand`. */
  possessMessages(subset: string | null, hand: PuppetHand = null): object[] {
    return this.others.map((person) => possessMessage(subset, hand, person));
  }

  /** Release every person this page ever sent, in view or not. */
  releaseMessages(): object[] {
    return [...this.seqs.keys()].map((person) => ({ type: 'release', person }));
  }

  /** The server user name of person `id`, for a page connected as `client`. */
  user(client: string, id: number): string {
    return id === this.main ? client : `${client}p${id}`;
  }

  forget(): void {
    this.tracks.forget();
    this.ids = [];
    this.main = null;
    this.mappers.clear();
    this.frames.clear();
  }
}
