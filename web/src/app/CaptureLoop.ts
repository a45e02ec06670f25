// This page's capture: camera → landmark worker → people with stable ids (People) → the followed person as
// a Kinect 20 skeleton, handed to the page for its skeleton channel, and every other person's frame on a
// channel of their own. Detection runs in a worker; the loop offers it the camera's newest frame whenever
// it is idle, so the page never waits on it.
import type { Camera } from '../capture/Camera';
import type { Detection } from '../capture/detection';
import { personHands, type PersonHand } from '../capture/hands';
import { LandmarkTracker } from '../capture/LandmarkTracker';
import type { Vec3 } from '../net/protocol';
import { People } from './People';

/** One skeleton frame of the followed person: Kinect 20 joints in metres (null rows untracked). */
export interface UserFrame {
  positions: (Vec3 | null)[];
  tracked: boolean[];
  t: number; // when the camera frame was captured (ms since the epoch): latency counts from it
  hands: PersonHand[]; // [left, right], null when not seen
  face: Record<string, number> | null; // blendshape weights of the face in view (one face is looked for)
}

/** What the capture loop tells the page. */
export interface CaptureHost {
  say(text: string, error?: boolean): void;
  /** The camera started (true) or stopped. */
  running(on: boolean): void;
  /** The followed person's frame, or null when nobody is in view (the page then holds the pose). */
  user(frame: UserFrame | null): void;
  /** A skeleton message of one of the other people in view (it names its "person"). */
  send(message: object): void;
}

export class CaptureLoop {
  readonly tracker: LandmarkTracker;
  /** The people in this camera's view: the main one drives this page's channel, the others their own. */
  readonly people: People;
  trackedJoints = 0;
  handsSeen: [boolean, boolean] = [false, false]; // [left, right] in the newest frame sent
  trackingLost = false;
  /** What the address allows (`?nohands`, `?noface`, `?notiles` turn one off) and what the page uses now. */
  private readonly allowed: { hands: boolean; face: boolean; tiles: boolean };
  private wanted = { hands: false, face: false };

  constructor(readonly camera: Camera, private readonly host: CaptureHost) {
    const query = new URLSearchParams(location.search);
    this.allowed = { hands: !query.has('nohands'), face: !query.has('noface'), tiles: !query.has('notiles') };
    this.tracker = new LandmarkTracker({
      wasm: new URL('mediapipe/tasks-vision/', document.baseURI).href,
      models: new URL('models/', document.baseURI).href,
      delegate: (query.get('delegate')?.toUpperCase() as 'CPU' | 'GPU' | null) ?? 'auto',
      numPoses: 4,
      features: { hands: false, face: false, tiles: this.allowed.tiles },
    });
    this.people = new People((m) => this.host.send(m));
  }

  /** Look for hands and a face only while something uses them (an avatar, the face puppet, a hand puppet):
   * each costs the worker a landmarker to make, seconds under SwiftShader, and a search on every frame.
   * Only a change is passed on, so features set on the tracker directly stay until the use changes. */
  want(hands: boolean, face: boolean): void {
    if (hands === this.wanted.hands && face === this.wanted.face) return;
    this.wanted = { hands, face };
    this.tracker.setFeatures({ hands: hands && this.allowed.hands, face: face && this.allowed.face,
      tiles: this.allowed.tiles });
  }

  async toggle(): Promise<void> {
    if (this.camera.running) {
      this.camera.stop();
      this.people.forget();
      this.host.running(false);
      return;
    }
    try {
      this.host.say('starting the camera and the pose tracker…');
      await this.camera.start();
      await this.tracker.init();
      this.host.running(true);
      this.host.say('step back until your whole body is in view, then “Fit to me” and “Possess”');
      void this.loop();
    } catch (err) {
      this.camera.stop();
      this.host.say(`camera: ${(err as Error).message}`, true);
    }
  }

  private async loop(): Promise<void> {
    this.tracker.onDetection = (d) => this.onDetection(d);
    while (this.camera.running) {
      await this.tracker.offer(this.camera.video);
      await new Promise((resolve) => setTimeout(resolve, 5));
    }
  }

  private onDetection(d: Detection): void {
    if (!this.camera.running) return;
    const main = this.people.update(d).find((p) => p.main);
    if (main) {
      this.trackedJoints = main.frame.tracked.filter(Boolean).length;
      this.trackingLost = false;
      const hands = personHands(main.pose, main.frame, d.hands, d.width / d.height);
      this.handsSeen = [hands[0] !== null, hands[1] !== null];
      this.host.user({ ...main.frame, t: performance.timeOrigin + d.t, hands, face: d.faces[0]?.scores ?? null });
    } else {
      this.trackingLost = true;
      this.trackedJoints = 0;
      this.handsSeen = [false, false];
      this.host.user(null);
    }
  }
}
