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

/** Note the capture time (`tSource`, ms since the epoch) and count of the newest transforms block the page
 * received for each mesh, as `window.shown[meshId] = { t, count }` (idempotent). */
export const watchTransforms = (page) => page.evaluate(() => {
  if (window.shown) return;
  window.shown = {};
  const studio = window.kinetre.studio;
  const onTransforms = studio.onTransforms.bind(studio);
  studio.onTransforms = (block) => {
    const seen = window.shown[block.meshId];
    window.shown[block.meshId] = { t: block.tSource, count: (seen?.count ?? 0) + 1 };
    onTransforms(block);
  };
});

/** The page's clock now (ms since the epoch, as the capture times its frames carry). */
export const pageNow = (page) => page.evaluate(() => performance.timeOrigin + performance.now());

/** Wait until the page has shown, for the default mesh (or `meshId`), a pose solved from frames captured
 * after `since` (page clock, ms; a release's rest pose counts from when the server let go); its capture time
 * (watchTransforms first). */
export async function shownAfter(page, since, meshId = null, timeout = 120000) {
  const id = meshId ?? await page.evaluate(() => window.kinetre.state().meshId);
  return until(page, ([m, t]) => (window.shown[m]?.t ?? 0) > t && window.shown[m].t, [id, since], timeout);
}

/** Wait until the page has shown a pose from frames captured after `since`, then one from a later capture
 * still: by then every user's newest frame that the server solved with came after `since`. */
export async function shownSince(page, since, meshId = null, timeout = 120000) {
  await shownAfter(page, await shownAfter(page, since, meshId, timeout), meshId, timeout);
}

/** Wait until the page has received `count` more transforms blocks for the default mesh than it had when
 * this was called (watchTransforms first): a recording holds at least that many solved poses. */
export async function moreTransforms(page, count, timeout = 120000) {
  const id = await page.evaluate(() => window.kinetre.state().meshId);
  const start = await page.evaluate((m) => window.shown[m]?.count ?? 0, id);
  await until(page, ([m, n]) => (window.shown[m]?.count ?? 0) >= n, [id, start + count], timeout);
}
