// Run the page's skeleton-message fields for hands and face (web/src/net/handsFace.ts, bundled by esbuild as
// FILE) on cases from stdin: [{hands, scores}] -> [{fields, back}] as JSON, `back` the scores read back from
// the fields' blendshapes (faceScores).
// Usage: node hands_face_wire_ts.mjs FILE < cases.json
import { readFileSync } from "node:fs";
import { pathToFileURL } from "node:url";

const { faceScores, handsFaceFields } = await import(pathToFileURL(process.argv[2]).href);
const cases = JSON.parse(readFileSync(0, "utf8"));
process.stdout.write(JSON.stringify(cases.map((c) => {
  const fields = handsFaceFields(c.hands, c.scores);
  return { fields, back: faceScores(fields.blendshapes) };
})));
