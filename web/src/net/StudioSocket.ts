// One WebSocket to the studio server: sends JSON commands and skeleton frames, dispatches what comes back.
// Reconnects after a drop, as the same client (see `resume`); skeleton frames sent while the socket is
// busy are dropped (the newest wins).
import { decodeTransforms, type ServerMessage, type TransformBlock } from './protocol';

export interface SocketHandlers {
  onMessage(message: ServerMessage): void;
  onTransforms(block: TransformBlock): void;
  onConnection(open: boolean): void;
}

export class StudioSocket {
  client = '';
  private ws: WebSocket | null = null;
  private closed = false;
  sentFrames = 0;
  droppedFrames = 0;
  sceneLost = false; // the studio says its scene (a `kinetre scene` process) stopped answering
  refused = ''; // why the studio closed the socket for good (a room token missing or wrong)
  // "client.token" from the welcome: after a dropped connection the page comes back as the same user,
  // possessing what it possessed, if it returns within the server's grace period
  private resume = '';

  constructor(private readonly url: string, private readonly handlers: SocketHandlers) {}

  connect(): void {
    let url = this.url;
    if (this.resume) url += `${url.includes('?') ? '&' : '?'}resume=${encodeURIComponent(this.resume)}`;
    const ws = new WebSocket(url);
    ws.binaryType = 'arraybuffer';
    ws.onopen = () => this.handlers.onConnection(true);
    ws.onclose = (event: CloseEvent) => {
      if (event.code === 4401) this.refused = event.reason || 'this room needs its token';
      this.handlers.onConnection(false);
      if (!this.closed && !this.refused) setTimeout(() => this.connect(), 1000);
    };
    let received = 0;
    ws.onmessage = (event: MessageEvent) => {
      // acknowledge every message: the server keeps only a few in flight, so a busy page gets fresh
      // frames instead of seconds of stale ones queued in network buffers
      ws.send(JSON.stringify({ type: 'ack', received: ++received }));
      if (event.data instanceof ArrayBuffer) {
        const block = decodeTransforms(event.data);
        if (block) this.handlers.onTransforms(block);
        return;
      }
      const message = JSON.parse(event.data as string) as ServerMessage;
      if (message.type === 'welcome') {
        this.client = message.client;
        this.resume = message.resume ?? '';
      }
      if (message.type === 'state') this.sceneLost = Boolean(message.scene_lost);
      this.handlers.onMessage(message);
    };
    this.ws = ws;
  }

  get open(): boolean {
    return this.ws?.readyState === WebSocket.OPEN;
  }

  send(message: object): boolean {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    this.ws.send(JSON.stringify(message));
    return true;
  }

  /** A skeleton frame; skipped when more than 64 kB are still waiting to go out (a slow link). */
  sendFrame(message: object): void {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN || this.ws.bufferedAmount > 65536) {
      this.droppedFrames++;
      return;
    }
    this.ws.send(JSON.stringify(message));
    this.sentFrames++;
  }

  close(): void {
    this.closed = true;
    this.ws?.close(1000); // with its code: the server forgets this user at once instead of awaiting a reconnect
  }
}
