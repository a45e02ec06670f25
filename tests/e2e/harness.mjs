// What every browser driver shares: playwright-core from web/node_modules (it drives Debian's Chromium, no
// browser download), and the run-and-report step: one JSON object on the last line of stdout, which
// tests/e2e/node_driver.py reads and whose `ok` it asserts.
import { createRequire } from 'node:module';
import { writeFileSync } from 'node:fs';

const require = createRequire(new URL('../../web/package.json', import.meta.url));
export const { chromium } = require('playwright-core');

/** Run `scenario`, mark `result` ok or record the error, then print it (and write it to `out`, if given).
 * `cleanup` runs whatever happened (e.g. closing the browser); `t0` adds the seconds taken. */
export async function report(result, scenario, { t0 = null, out = null, cleanup = null } = {}) {
  try {
    await scenario();
    result.ok = true;
  } catch (err) {
    result.ok = false;
    result.error = String(err && err.stack ? err.stack : err);
  } finally {
    if (cleanup) await cleanup();
  }
  if (t0 !== null) result.seconds = (Date.now() - t0) / 1000;
  const text = JSON.stringify(result);
  if (out) writeFileSync(out, text);
  process.stdout.write(text + '\n');
}

/** Debian's Chromium, headless, with `video` (a .y4m file) as its camera and `audio` (a WAV) as its
 * microphone, both looped. Chromium refuses fake-capture paths that contain "..": give absolute ones. */
export function launchWithCamera(video, audio = null) {
  const args = [
    '--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--disable-background-timer-throttling', '--disable-renderer-backgrounding',
    '--disable-backgrounding-occluded-windows', '--autoplay-policy=no-user-gesture-required',
    '--use-fake-ui-for-media-stream', '--use-fake-device-for-media-stream',
  ];
  if (video) args.push(`--use-file-for-fake-video-capture=${video}`);
  if (audio) args.push(`--use-file-for-fake-audio-capture=${audio}`);
  return chromium.launch({ executablePath: '/usr/bin/chromium', headless: true, args });
}

/** The studio page's test-hook state, without the (large) skeleton. */
export const state = (page) => page.evaluate(() => {
  const s = window.kinetre.state();
  delete s.skeleton;
  return s;
});

/** The predicate's truthy value, as seen at that moment (a later read may see the dancer moved on). */
export async function until(page, predicate, arg, timeout = 60000) {
  const handle = await page.waitForFunction(predicate, arg, { timeout, polling: 250 });
  return handle.jsonValue();
}
