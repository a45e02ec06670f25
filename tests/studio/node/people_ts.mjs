// Run the page's People (web/src/app/People.ts, with PersonTracks, bundled by esbuild into BUNDLE) on a
// fixture: {frames: [{t, width, height, centres: [[x, y] per person]}]} from stdin, each person a standing
// figure of 33 landmarks around their torso centre. Prints, per frame, the ids in detection order, the main
// person (and whether this frame saw them), the messages sent for the other people, and what Possess (by the body, and by the right hand) and
// Release would send.
// Usage: node people_ts.mjs BUNDLE.mjs < fixture.json
import { readFileSync } from "node:fs";
import { pathToFileURL } from "node:url";

const { People } = await import(pathToFileURL(process.argv[2]).href);
const fixture = JSON.parse(readFileSync(0, "utf8"));

function figure([cx, cy]) {
  // image landmarks: a 0.4-tall figure (image heights) centred on the torso; world landmarks in metres
  const image = Array.from({ length: 33 }, (_, i) => ({ x: cx, y: cy + (i >= 23 ? 0.1 : -0.1), z: 0, visibility: 1 }));
  for (const i of [11, 23]) image[i].x = cx - 0.03;
  for (const i of [12, 24]) image[i].x = cx + 0.03;
  const world = image.map((l, i) => ({ x: (l.x - cx) * 2, y: i >= 27 ? 0.9 : (l.y - cy) * 2, z: 0, visibility: 1 }));
  return { image, world };
}

const sent = [];
const people = new People((m) => sent.push(m));
const out = fixture.frames.map((f) => {
  const before = sent.length;
  const frames = people.update({ t: f.t, ms: 0, width: f.width, height: f.height, poses: f.centres.map(figure), hands: [], faces: [] });
  return {
    ids: frames.map((p) => p.id),
    inView: people.ids,
    main: people.main,
    mainSeen: frames.some((p) => p.main),
    sent: sent.slice(before).map((m) => ({ person: m.person, seq: m.seq, tracked: m.tracked.filter(Boolean).length })),
    possess: people.possessMessages(null),
    possessByHand: people.possessMessages("legs", "right"),
    release: people.releaseMessages(),
    user: people.ids.map((id) => people.user("c7", id)),
  };
});
process.stdout.write(JSON.stringify(out));
