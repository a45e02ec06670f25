// An avatar's fingers and face driven by a real camera image, in Debian's Chromium (tests/e2e/test_avatar_page.py):
//   node driver_hands.mjs '{"url": "...", "query": "?nohands&noface...", "video": "...", "avatar": "..."}'
// The page starts with its hand and face landmarkers off: the avatar follows the body alone; then they are
// turned on and the avatar's finger bones and morph weights are read again.
import { resolve } from 'node:path';
import { launchWithCamera, report, until } from './harness.mjs';

const config = JSON.parse(process.argv[2]);
const result = { steps: [] };
const t0 = Date.now();
const log = (step, extra = {}) => result.steps.push({ step, s: (Date.now() - t0) / 1000, ...extra });
const avatar = (page) => page.evaluate(() => window.kinetre.state().avatar);

async function run() {
  const browser = await launchWithCamera(resolve(config.video));
  try {
    const page = await browser.newPage({ viewport: { width: 640, height: 480 } });
    page.setDefaultTimeout(120000);
    page.on('pageerror', (e) => log('page error', { message: String(e) }));
    await page.goto(config.url + config.query);
    await until(page, () => window.kinetre && window.kinetre.state().connected, null, 120000);
    await page.setInputFiles('#file', config.avatar);
    await until(page, () => window.kinetre.state().avatar.ready, null, 120000);
    // what the page hands the avatar from each detection: hands seen, a face seen
    await page.evaluate(() => {
      const host = window.kinetre.studio.capture.host;
      const user = host.user;
      window.seen = { frames: 0, hands: 0, faces: 0 };
      host.user = (frame) => {
        if (frame) {
          window.seen.frames++;
          window.seen.hands += frame.hands.filter(Boolean).length;
          window.seen.faces += frame.face ? 1 : 0;
        }
        user(frame);
      };
    });
    await page.keyboard.press('c');
    await until(page, () => window.kinetre.state().avatar.source === 'me' && window.kinetre.state().avatar.driven >= 3,
      null, 180000);
    const bodyOnly = [await avatar(page)];
    await until(page, (n) => window.kinetre.state().avatar.driven >= n, bodyOnly[0].driven + 3, 120000);
    bodyOnly.push(await avatar(page));
    result.bodyOnly = bodyOnly.map((a) => ({ fingerBones: a.fingerBones, morphs: a.morphs }));
    result.seenBodyOnly = await page.evaluate(() => ({ ...window.seen }));
    log('body only', { driven: bodyOnly[1].driven });
    await page.evaluate(() => window.kinetre.studio.capture.tracker.setFeatures({ hands: true, face: true, tiles: false }));
    try {
      await until(page, () => window.seen.hands >= 6 && window.seen.faces >= 3, null, 180000);
    } finally {
      result.seen = await page.evaluate(() => ({ ...window.seen }));
    }
    const a = await avatar(page);
    result.withHandsAndFace = { fingerBones: a.fingerBones, morphs: a.morphs };
    log('hands and face', { seen: result.seen });
  } finally {
    await browser.close();
  }
}

await report(result, run, { t0, out: config.out });
