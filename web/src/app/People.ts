// The people in this page's camera as studio users: each tracked person (a stable id from PersonTracks) is
// mapped to Kinect 20 with a mapper of their own and sent on a channel of their own. One of them, the
// "main" person, drives the page's own channel (the user the page's buttons and voice talk about); every
// other person is sent with a "person" field and becomes the server user `<client>p<id>`. Possess and
// release apply to them all, so two people in one view can carry one horse through a joint map.
import type { Detection, PoseLandmarks } from '../capture/detection';
import { KinectMapper, type KinectFrame } from '../capture/KinectMapper';
import { PersonTracks, distinctPoses } from '../capture/PersonTracks';
import { possessMessage, type PuppetHand } from '../rigging/PuppetControl';

export interface PersonFrame {
  id: number;
  main: boolean; // sent on the page's own channel
  frame: KinectFrame;
  pose: PoseLandmarks; // the landmarks it was mapped from
}

export class People {
  readonly tracks = new PersonTracks();
  /** Ids in view in the newest detection, ascending. */
  ids: number[] = [];
  /** The person the page's own channel follows: kept while in view, else the lowest id in view. */
  main: number | null = null;
  private readonly mappers = new Map<number, KinectMapper>();
  private readonly seqs = new Map<number, number>();
  /** The newest frame of each person in view. */
  readonly frames = new Map<number, KinectFrame>();

  constructor(private readonly sendFrame: (message: object) => void) {}

  /** Ids and Kinect frames of the people in `d`, in its order; the frames of all but the main one are sent. */
  update(d: Detection): PersonFrame[] {
    const poses = distinctPoses(d.poses, d.width / d.height);
    const ids = this.tracks.update(poses, d.width / d.height, d.t);
    this.ids = [...ids].sort((a, b) => a - b);
    if (this.ids.length && (this.main === null || !this.ids.includes(this.main))) this.main = this.ids[0];
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

  /** The other people in view (not the main one), ascending: the users `<client>p<id>`. */
  get others(): number[] {
    return this.ids.filter((id) => id !== this.main);
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
