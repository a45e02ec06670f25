// A hand puppet in Debian's Chromium (tests/e2e/test_puppet_page.py): the page opened with ?puppet=right, its
// fake camera showing a person with their hands in view; Possess makes their right hand possess the mesh.
// Prints one JSON object.
//   node driver_puppet.mjs '{"url": "...", "video": "camera.y4m", "artifacts": "..."}'
import { mkdirSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { launchWithCamera, report, state, until } from './harness.mjs';

const config = JSON.parse(process.argv[2]);
const result = { errors: [] };
const browser = await launchWithCamera(resolve(config.video));
await report(result, async () => {
  const page = await browser.newPage({ viewport: { width: 720, height: 540 } });
  page.setDefaultTimeout(120000);
  page.on('pageerror', (e) => result.errors.push(String(e)));
  await page.goto(config.url + '/?noshadows&noface&puppet=right');
  await page.waitForFunction(() => window.kinetre && window.kinetre.state().meshId !== null, null, { timeout: 60000 });
  result.chosen = await page.locator('#puppet').inputValue();
  await page.keyboard.press('c');
  // the body tracked and the hands sent with its frames (the worker finds hands in a frame or two)
  await until(page, () => window.kinetre.state().trackedJoints >= 12 && window.kinetre.state().handsSeen[1], null, 180000);
  await until(page, () => window.kinetre.state().users.some((u) => u.client === window.kinetre.state().client && u.frames > 0),
    null, 60000);
  // a hand the worker missed in the newest frame is refused: show it again, as a user would, up to 4 times
  for (let attempt = 0; attempt < 4 && !(await state(page)).possessing; attempt++) {
    if (attempt) await until(page, () => window.kinetre.state().handsSeen[1], null, 120000); // the hand in view again
    await page.evaluate(() => { document.querySelector('#message').className = ''; });
    await page.keyboard.press('p');
    await until(page, () => {
      const s = window.kinetre.state();
      return s.possessing || document.querySelector('#message').className === 'error';
    }, null, 120000);
  }
  const s = await state(page);
  result.message = s.message;
  result.me = s.users.find((u) => u.client === s.client) ?? null;
  result.status = await page.locator('#status').textContent();
  const samples = [];
  for (let i = 0; i < 6; i++) {
    samples.push((await state(page)).vertices);
    await page.waitForTimeout(500);
  }
  result.samples = samples;
  mkdirSync(config.artifacts, { recursive: true });
  await page.screenshot({ path: join(config.artifacts, 'puppet.png') });
}, { cleanup: () => browser.close() });
