// Run the page's TypeScript retargeter (web/src/avatar/retarget.ts, bundled by esbuild into BUNDLE) on a
// fixture: {plan, positions (T x 20 x 3, null = untracked), tracked (T x 20)} from stdin; prints
// {world, local} per frame as JSON.
// Usage: node retarget_ts.mjs BUNDLE.mjs < fixture.json
import { readFileSync } from "node:fs";
import { pathToFileURL } from "node:url";

const { Retargeter } = await import(pathToFileURL(process.argv[2]).href);
const fixture = JSON.parse(readFileSync(0, "utf8"));
const retargeter = new Retargeter(fixture.plan);
const frames = fixture.positions.map((p, t) => retargeter.frame(p, fixture.tracked[t]));
process.stdout.write(JSON.stringify({ world: frames.map((f) => f.world), local: frames.map((f) => f.local) }));
