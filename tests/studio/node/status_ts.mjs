// Run the page's status line (web/src/app/StatusLine.ts, bundled by esbuild into BUNDLE) on the facts read
// from stdin; prints the line.
// Usage: node status_ts.mjs BUNDLE.mjs < facts.json
import { readFileSync } from "node:fs";
import { pathToFileURL } from "node:url";

const { statusLine } = await import(pathToFileURL(process.argv[2]).href);
process.stdout.write(statusLine(JSON.parse(readFileSync(0, "utf8"))));
