// Run the page's hand assignment (web/src/capture/hands.ts, bundled by esbuild into DIR) on cases from
// stdin: [{pose, frame, hands, aspect}] -> [[left, right]] as JSON.
// Usage: node person_hands_ts.mjs DIR < cases.json
import { readFileSync } from "node:fs";
import { pathToFileURL } from "node:url";

const { personHands } = await import(pathToFileURL(`${process.argv[2]}/hands.js`).href);
const cases = JSON.parse(readFileSync(0, "utf8"));
process.stdout.write(JSON.stringify(cases.map((c) => personHands(c.pose, c.frame, c.hands, c.aspect))));
