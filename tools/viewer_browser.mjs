// Drives the syndds viewer page in headless Chromium (Debian's chromium through playwright-core
// from services/viewer/web/node_modules): used by launch_scripts/view.sh --screenshot and the
// viewer's browser tests (tests/viewer/).
//
//   node tools/viewer_browser.mjs URL --screenshot FILE [--time S] [--camera follow|orbit|top]
//       [--vehicle ID] [--size WxH]
import { createRequire } from 'node:module';
import { existsSync } from 'node:fs';

const require = createRequire(new URL('../services/viewer/web/package.json', import.meta.url));

export const CHROMIUM = process.env.SYNDDS_CHROMIUM || '/usr/bin/chromium';

/// Headless Chromium, with `args` added to its command line.
export async function launchChromium(args = []) {
  const { chromium } = require('playwright-core');
  if (!existsSync(CHROMIUM)) throw new Error(`${CHROMIUM} not found (apt-get install chromium)`);
  // WebGL without a GPU: SwiftShader. No sandbox: tests and CI run as root.
  return chromium.launch({
    executablePath: CHROMIUM,
    args: ['--no-sandbox', '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', ...args],
  });
}

/// Opens the viewer at `url` and waits until it has drawn its first picture (in `browser`, or in
/// a Chromium started for it).
export async function openViewer(url, { width = 1280, height = 720, timeoutMs = 60000, browser = null } = {}) {
  browser = browser || await launchChromium();
  const page = await browser.newPage({ viewport: { width, height } });
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto(url);
  await page.waitForFunction(() => window.syndds && (window.syndds.ready || window.syndds.error),
    null, { timeout: timeoutMs });
  const error = await page.evaluate(() => window.syndds.error);
  if (error || errors.length) {
    await browser.close();
    throw new Error(`the page failed: ${error || errors.join('; ')}`);
  }
  return { browser, page, errors };
}

async function cli(argv) {
  const url = argv[0];
  const opt = {};
  for (let k = 1; k < argv.length; k += 2) opt[argv[k].replace(/^--/, '')] = argv[k + 1];
  if (!url || !opt.screenshot) {
    console.error('usage: viewer_browser.mjs URL --screenshot FILE [--time S] [--camera C] [--vehicle ID] [--size WxH]');
    process.exit(1);
  }
  const [w, h] = (opt.size || '1280x720').split('x').map(Number);
  const { browser, page } = await openViewer(url, { width: w, height: h });
  try {
    if (opt.vehicle) await page.evaluate((id) => window.syndds.select(id), opt.vehicle);
    await page.evaluate((t) => window.syndds.setTime(t), opt.time === undefined ? Infinity : Number(opt.time));
    if (opt.camera) await page.evaluate((c) => window.syndds.setView(c), opt.camera);
    await page.evaluate(() => window.syndds.redraw());
    await page.screenshot({ path: opt.screenshot });
    console.log(`view: saved ${opt.screenshot}`);
  } finally {
    await browser.close();
  }
}

if (import.meta.url === `file://${process.argv[1]}`) {
  cli(process.argv.slice(2)).catch((e) => { console.error(`view: ${e.message}`); process.exit(2); });
}
