// Run the page's MediaPipe → Kinect-20 conversion (web/src/capture/KinectMapper.ts, bundled by esbuild into
// BUNDLE) on the frames read from stdin: {"aspect", "frames": [{"world": [33 landmarks], "image": [...]}]},
// each landmark {x, y, z, visibility}; prints one {positions, tracked} per frame, in order, as JSON.
// Usage: node kinect_mapper_ts.mjs BUNDLE.mjs < frames.json
import { readFileSync } from "node:fs";
import { pathToFileURL } from "node:url";

const { KinectMapper } = await import(pathToFileURL(process.argv[2]).href);
const fixture = JSON.parse(readFileSync(0, "utf8"));
const mapper = new KinectMapper(fixture.aspect);
process.stdout.write(JSON.stringify(fixture.frames.map((f) => mapper.map(f.world, f.image))));
