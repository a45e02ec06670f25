// The avatar in the studio page, in Debian's Chromium (playwright-core): upload a rigged humanoid, watch the
// sample motion drive it, skin one given frame (for a comparison with Python), record a take, edit the
// bone map, drive it from the (fake) webcam, and drop a fox (refused as an avatar, loaded for possession).
// Prints one JSON object.
//   node driver_avatar.mjs '{"url": "...", "avatar": "...", "fox": "...", "frame": {...}, "video": "...", ...}'
import { mkdirSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { chromium, report } from './harness.mjs';

const config = JSON.parse(process.argv[2]);
const result = { steps: [] };
const t0 = Date.now();
const log = (step, extra = {}) => result.steps.push({ step, s: (Date.now() - t0) / 1000, ...extra });
const avatar = (page) => page.evaluate(() => window.kinetre.state().avatar);
const waitFor = (page, fn, arg, timeout = 120000) => page.waitForFunction(fn, arg, { timeout, polling: 250 });

function spread(samples) {
  let best = 0;
  for (const a of samples) for (const b of samples) a.forEach((p, v) => { best = Math.max(best, Math.hypot(...p.map((x, k) => x - b[v][k]))); });
  return best;
}

const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', headless: true,
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-background-timer-throttling',
    '--disable-renderer-backgrounding', '--disable-backgrounding-occluded-windows',
    '--use-fake-ui-for-media-stream', '--use-fake-device-for-media-stream',
    `--use-file-for-fake-video-capture=${resolve(config.video)}`] });
await report(result, async () => {
  const page = await browser.newPage({ viewport: { width: 720, height: 540 } });
  page.on('pageerror', (e) => log('page error', { message: String(e) }));
  await page.goto(config.url + '?noshadows');
  await waitFor(page, () => window.kinetre && window.kinetre.state().meshId !== null);

  await page.setInputFiles('#file', config.avatar);
  await waitFor(page, () => window.kinetre.state().avatar.ready);
  await waitFor(page, () => window.kinetre.state().avatar.driven > 10);
  log('avatar driven', { source: (await avatar(page)).source });
  const watch = async () => {
    const samples = [];
    for (let i = 0; i < 8; i++) { samples.push((await avatar(page)).vertices); await page.waitForTimeout(400); }
    return spread(samples);
  };
  result.spread = await watch();
  mkdirSync(config.artifacts, { recursive: true });
  await page.screenshot({ path: join(config.artifacts, 'studio-avatar.png') });

  // one given frame, as this page's camera would deliver it: the page's skinned vertices and placement
  result.skinned = await page.evaluate(({ positions, tracked }) => {
    const studio = window.kinetre.studio;
    studio.avatars.drive(positions, tracked, 'me');
    const s = studio.avatars.state();
    return { vertices: s.vertices, model: studio.avatars.holder.children[0].matrixWorld.elements };
  }, config.frame);

  await page.keyboard.press(' ');
  await waitFor(page, () => window.kinetre.state().avatar.recording, null, 30000);
  const recordedFrom = (await avatar(page)).driven; // the take: while the avatar is driven 10 more times
  await waitFor(page, (n) => window.kinetre.state().avatar.driven >= n, recordedFrom + 10);
  await page.keyboard.press(' ');
  await page.waitForSelector('#downloads a:has-text("avatar GLB")', { timeout: 240000 }); // the take exported
  result.downloads = await page.$$eval('#downloads a', (links) => links.map((a) => [a.textContent, a.getAttribute('href')]));
  log('avatar take recorded');

  await page.click('#avatar-edit-map');
  await page.waitForSelector('#avatar-map select[name="ShoulderCenter"]');
  await page.selectOption('#avatar-map select[name="ShoulderCenter"]', config.shoulderCenter);
  await page.click('#avatar-map-save');
  await waitFor(page, () => /avatar map saved/.test(document.querySelector('#message').textContent));
  result.mapped = await page.evaluate(() => window.kinetre.studio.avatars.payload.how);
  result.mapLink = await page.getAttribute('#avatar-map-file', 'href');
  log('map saved');

  await page.setInputFiles('#file', config.fox);
  // once the fox has loaded as a mesh, the page still says why it is not an avatar
  await waitFor(page, () => window.kinetre.state().meshName === 'Fox.glb'
    && /loaded as a mesh instead/.test(document.querySelector('#message').textContent), null, 120000);
  result.foxMessage = await page.textContent('#message');
  result.meshAfterFox = await page.evaluate(() => window.kinetre.state().meshName);

  // the webcam's skeleton (a dancer on the fake camera) takes over from the sample motion
  await page.keyboard.press('c');
  await waitFor(page, () => window.kinetre.state().trackedJoints >= 12 && window.kinetre.state().avatar.source === 'me',
    null, 180000);
  result.cameraSpread = await watch();
  log('camera drives the avatar', { source: (await avatar(page)).source });
}, { cleanup: () => browser.close() });
