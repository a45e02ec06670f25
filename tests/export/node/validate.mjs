// Validate one glTF/GLB file with the Khronos glTF validator; print its JSON report on stdout.
// Usage: node validate.mjs FILE   (exit 0 whatever the report says; the Python test reads the counts)
import { readFile } from "node:fs/promises";
import path from "node:path";
import validator from "gltf-validator";

const file = process.argv[2];
const data = new Uint8Array(await readFile(file));
const report = await validator.validateBytes(data, {
  uri: path.basename(file),
  maxIssues: 100,
  // .gltf files may reference .bin/images beside them
  externalResourceFunction: (uri) =>
    readFile(path.join(path.dirname(file), decodeURIComponent(uri))).then((b) => new Uint8Array(b)),
});
process.stdout.write(JSON.stringify(report));
