// Run the page's StudioSocket (web/src/net/StudioSocket.ts, bundled by esbuild into BUNDLE) against a stand-in
// WebSocket: the server's welcome, then a dropped connection and a closing one. Prints the URL of every
// connection the socket opened, and the close code it sent when the page closed it.
// Usage: node socket_ts.mjs BUNDLE.mjs
import { pathToFileURL } from "node:url";

const sockets = [];
globalThis.WebSocket = class {
  static OPEN = 1;
  constructor(url) {
    this.url = url;
    this.readyState = 1;
    this.closedWith = null;
    sockets.push(this);
  }
  send() {}
  close(code) {
    this.closedWith = code ?? null;
  }
};
const realTimeout = globalThis.setTimeout;
globalThis.setTimeout = (fn) => realTimeout(fn, 0); // the reconnect's pause, without the wait

const { StudioSocket } = await import(pathToFileURL(process.argv[2]).href);
const socket = new StudioSocket("ws://studio/ws?token=t", { onMessage() {}, onTransforms() {}, onConnection() {} });
socket.connect();
sockets[0].onopen();
sockets[0].onmessage({ data: JSON.stringify({ type: "welcome", client: "c7", resume: "c7.s3cret-_x", channel: "x" }) });
sockets[0].onclose({ code: 1006 }); // dropped
await new Promise((r) => realTimeout(r, 20));
socket.close();
console.log(JSON.stringify({ urls: sockets.map((s) => s.url), closeCode: sockets.at(-1).closedWith, client: socket.client }));
