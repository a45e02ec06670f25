// A take, started and stopped together: the server records every solved frame (GLB, BVH, skeleton stream,
// node transforms), an avatar beside the mesh records its own take, and the canvas records a WebM. When it
// stops, the files are offered for download and the node transforms go to the physics replay.
import { CanvasRecorder } from '../record/CanvasRecorder';
import { type TakeFiles, TakeRecorder } from '../record/TakeRecorder';

export interface Download {
  label: string;
  href: string;
  file: string;
}

/** What a take session needs from the page. */
export interface TakeHost {
  say(text: string, error?: boolean): void;
  downloads(links: Download[]): void;
  /** A take recorded beside the server's (the avatar's), started and stopped with it. */
  readonly companion: { startRecording(): void; stopRecording(): Promise<Download[]> };
  /** The recorded take (each mesh's node transforms go to the physics replay). */
  recorded(take: TakeFiles): void;
}

export class TakeSession {
  readonly server = new TakeRecorder();
  readonly video: CanvasRecorder;

  constructor(canvas: HTMLCanvasElement, private readonly host: TakeHost) {
    this.video = new CanvasRecorder(canvas);
  }

  get recording(): boolean {
    return this.server.recording;
  }

  /** The last take the server exported. */
  get last(): TakeFiles | null {
    return this.server.last;
  }

  async toggle(): Promise<void> {
    const host = this.host;
    try {
      if (!this.server.recording) {
        await this.server.start();
        host.companion.startRecording();
        this.video.start();
        host.downloads([]);
        host.say('recording… press Space or Record again to stop');
        return;
      }
      const companion = host.companion.stopRecording().catch((e: Error) => { host.say(e.message, true); return []; });
      const [take, webm] = await Promise.all([this.server.stop(), this.video.stop()]).catch(async (err) => {
        host.downloads(await companion); // the avatar's take stands on its own
        throw err;
      });
      const others = await companion;
      host.recorded(take);
      // each mesh's files alike, named after the mesh when the take has several
      const links: Download[] = take.meshes.flatMap((m) => Object.entries(m.files)
        .filter(([kind]) => kind !== 'transforms').map(([kind, href]) => ({
          label: (kind === 'stream' ? 'skeleton stream' : kind.toUpperCase()) + (take.meshes.length > 1 ? ` (${m.name})` : ''),
          href, file: href.split('/').pop() as string,
        })));
      links.push(...others);
      if (webm) links.push({ label: 'WebM', href: URL.createObjectURL(webm), file: `kinetre-${take.take}.webm` });
      host.downloads(links);
      host.say(`take ${take.take}: ${take.frames} frames at ${take.fps} fps`);
    } catch (err) {
      await this.video.stop();
      host.say((err as Error).message, true);
    }
  }
}
