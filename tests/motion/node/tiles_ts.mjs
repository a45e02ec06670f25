// Run the page's square search geometry and merge (web/src/capture/tiles.ts, bundled by esbuild into BUNDLE)
// on a fixture from stdin: {tiles: [[width, height, overlap]], toImage: [{tile, marks, width, height}],
// distinct: [{points, scores}]}. Prints the answers in the same shape.
// Usage: node tiles_ts.mjs BUNDLE.mjs < fixture.json
import { readFileSync } from "node:fs";
import { pathToFileURL } from "node:url";

const { squareTiles, toImage, distinct } = await import(pathToFileURL(process.argv[2]).href);
const fixture = JSON.parse(readFileSync(0, "utf8"));
process.stdout.write(JSON.stringify({
  tiles: fixture.tiles.map(([w, h, overlap]) => squareTiles(w, h, overlap).map((t) => [t.x, t.y, t.width, t.height])),
  toImage: fixture.toImage.map(({ tile, marks, width, height }) =>
    toImage({ x: tile[0], y: tile[1], width: tile[2], height: tile[3] }, marks.map(([x, y, z]) => ({ x, y, z })), width, height)
      .map((l) => [l.x, l.y, l.z])),
  distinct: fixture.distinct.map(({ points, scores }) => distinct(points, scores)),
}));
