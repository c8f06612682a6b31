// The viewer in a real headless browser (Debian's chromium through playwright-core): one case
// per invocation, run by tests/viewer/browser_tests.sh, which starts the programs.
//   node browser_tests.mjs replay URL SHOT.png        default scenario, recorded
//   node browser_tests.mjs ruts URL SHOT.png          scm_crossing, recorded
//   node browser_tests.mjs contact URL SHOT.png       a recorded head-on: its contact marks
//   node browser_tests.mjs live URL                   a live scm_crossing run
//   node browser_tests.mjs watch URL [sensors]        a live run: states arrive (with
//                                                     `sensors`: lead's camera and lidar too);
//                                                     then watches until killed
//   node browser_tests.mjs origin URL LIVE_URL        a replay viewer (URL) and a live one:
//                                                     other sites' pages cannot reach either
import assert from 'node:assert/strict';
import http from 'node:http';
import { launchChromium, openViewer } from '../../tools/viewer_browser.mjs';

const [kind, url, shot] = process.argv.slice(2);
const log = (...a) => console.log(`browser_tests ${kind}:`, ...a);

async function moveSlider(page, value) {
  // As a person does: the slider's value changes and it says so.
  await page.$eval('#slider', (el, v) => { el.value = String(v); el.dispatchEvent(new Event('input')); }, value);
}

async function replay() {
  const { browser, page } = await openViewer(url);
  try {
    const info = await page.evaluate(() => ({
      frames: window.syndds.frames, vehicles: [...window.syndds.state.vehicles.keys()] }));
    log(JSON.stringify(info));
    assert.deepEqual(info.vehicles.sort(), ['lead', 'loop', 'scurve']);
    assert.ok(info.frames > 100, 'every recorded frame is loaded');
    // Obstacles and bodies from the sensors' OBJ meshes (config/meshes): rock, bush, two trees.
    const meshes = await page.evaluate(() => window.syndds.meshStats());
    log('meshes', JSON.stringify(meshes));
    assert.deepEqual(meshes, { obstacles: 4, vehicles: 3, errors: [] });
    await page.evaluate(() => window.syndds.setView('top'));
    await moveSlider(page, 0);
    const before = await page.evaluate(() => window.syndds.vehicleScreenPositions());
    await moveSlider(page, info.frames - 1);
    const after = await page.evaluate(() => window.syndds.vehicleScreenPositions());
    for (const id of info.vehicles) {
      const moved = Math.hypot(after[id][0] - before[id][0], after[id][1] - before[id][1]);
      log(`${id} moved ${moved.toFixed(1)} px on screen`);
      assert.ok(moved > 20, `${id} moves when the slider moves`);
    }
    const readout = await page.textContent('#r-time');
    assert.match(readout, /^\d+\.\d\d \/ \d+\.\d s/);
    // The whole run from above at its end: three vehicles and their tracks (docs/viewer.md).
    await moveSlider(page, info.frames - 1);
    await page.evaluate(() => window.syndds.setView('top'));
    const stats = await page.evaluate(() => window.syndds.pictureStats());
    log(JSON.stringify(stats));
    assert.ok(stats.notSky > 0.5 && stats.colours > 8, 'the picture shows the world');
    await page.screenshot({ path: shot });
    // Following the lead half way: its body mesh and four wheels (docs/viewer.md).
    await moveSlider(page, Math.floor(info.frames / 2));
    await page.evaluate(() => { window.syndds.select('lead'); window.syndds.setView('follow'); });
    const follow = await page.evaluate(() => window.syndds.pictureStats());
    assert.ok(follow.notSky > 0.3, 'the follow view shows the ground and the vehicle');
    await page.screenshot({ path: shot.replace(/\.png$/, '_follow.png') });
  } finally {
    await browser.close();
  }
}

async function ruts() {
  const { browser, page } = await openViewer(url);
  try {
    const frames = await page.evaluate(() => window.syndds.frames);
    await page.evaluate(() => window.syndds.setView('top'));
    // Straight down on the first vehicle's path, vehicles hidden: the same view at the start
    // (undisturbed soil) and at the end differs where the wheels went.
    await moveSlider(page, frames - 1);
    const end = await page.evaluate(() => window.syndds.vehicleState('a1').pose);
    await moveSlider(page, 0);
    const start = await page.evaluate(() => window.syndds.vehicleState('a1').pose);
    const cx = (start[0] + end[0]) / 2, cy = (start[1] + end[1]) / 2;
    await page.evaluate(([x, y]) => { window.syndds.showVehicles(false); window.syndds.lookDown(x, y, 10); }, [cx, cy]);
    const empty = await page.evaluate(() => window.syndds.pictureStats(true));
    const settled = await page.evaluate(() => window.syndds.soilStats());  // wheels at rest
    await moveSlider(page, frames - 1);
    await page.evaluate(([x, y]) => window.syndds.lookDown(x, y, 10), [cx, cy]);
    if (process.env.SYNDDS_DEBUG_SHOT) await page.screenshot({ path: process.env.SYNDDS_DEBUG_SHOT });
    const soil = await page.evaluate(() => window.syndds.soilStats());
    const rutted = await page.evaluate(() => window.syndds.pictureStats());
    log(JSON.stringify({ settled, soil, empty, rutted }));
    assert.ok(soil.maxDepth > 0.01, 'ruts deeper than 1 cm were replayed');
    assert.ok(soil.vertices > 10 * settled.vertices, 'the soil deformed along the paths');
    assert.ok(rutted.changed > 0.01, 'the ruts change the picture');
    await page.evaluate(() => { window.syndds.showVehicles(true); window.syndds.select('a2'); window.syndds.setView('follow'); });
    await moveSlider(page, Math.floor(frames / 2));
    await page.screenshot({ path: shot });
  } finally {
    await browser.close();
  }
}

async function live() {
  const { browser, page } = await openViewer(url);
  try {
    // While the run goes on: states arrive, the soil deforms in the page, the clock advances.
    await page.waitForFunction(() => window.syndds.updates > 0 && window.syndds.soilStats().vertices > 0,
      null, { timeout: 60000 });
    const first = await page.evaluate(() => window.syndds.state.frame);
    await page.waitForFunction((f) => window.syndds.state.frame > f + 10, first, { timeout: 60000 });
    const s = await page.evaluate(() => ({ frame: window.syndds.state.frame, soil: window.syndds.soilStats(),
      status: window.syndds.state.status, members: window.syndds.state.members.length,
      drawing: window.syndds.drawStats }));
    log(JSON.stringify(s));
    assert.equal(s.status, 'running');
    assert.ok(s.soil.maxDepth > 0, 'ruts appear while the run goes on');
  } finally {
    await browser.close();
  }
}

async function watch() {
  const { page } = await openViewer(url);
  log('page open');
  await page.waitForFunction(() => window.syndds.updates > 0, null, { timeout: 60000 });
  if (shot === 'sensors') {
    // The chosen vehicle's (lead's) camera image and lidar points reach the panel. The <img>
    // decodes a JPEG after it arrived (on a loaded machine well after, and the next image may
    // replace it first), so the wait is for an image the page decoded and showed, not for the
    // <img>'s current state.
    await page.waitForFunction(() => window.syndds.imagesShown > 0 && window.syndds.pointClouds > 0,
      null, { timeout: 60000 }).catch((e) => log('waiting for the camera image and lidar points:', e.message));
    const shown = await page.evaluate(() => ({ size: window.syndds.imageSize,
      label: document.getElementById('camera-label').textContent, images: window.syndds.images,
      imagesShown: window.syndds.imagesShown, pointClouds: window.syndds.pointClouds,
      frame: window.syndds.state.frame, status: window.syndds.state.status }));
    log(JSON.stringify(shown));
    assert.ok(shown.imagesShown > 0 && shown.size[0] > 0, 'the camera image is shown');
    assert.ok(shown.pointClouds > 0, 'the lidar points are shown');
  }
  log('watching');
  // What drawing costs the page, every second (bench_viewer.sh prints the last).
  for (;;) {
    await new Promise((r) => setTimeout(r, 1000));
    log('drawing', JSON.stringify(await page.evaluate(() => window.syndds.drawStats)));
  }
}

// In a page: opens the live viewer's WebSocket and fetches a run file of the replay viewer, as
// a script of that page may. ws: 'open' or 'refused'; run: 'read', 'status N' (a response the
// page may read) or 'blocked' (the browser kept the response from the page).
async function reachViewer({ live, replay }) {
  const ws = await new Promise((resolve) => {
    const s = new WebSocket(`${live.replace(/^http/, 'ws')}live`);
    const bound = setTimeout(() => resolve('no answer in 20 s'), 20000);
    s.onopen = () => { clearTimeout(bound); s.close(); resolve('open'); };
    s.onclose = () => { clearTimeout(bound); resolve('refused'); };
  });
  let run;
  try {
    const r = await fetch(`${replay}run/vehicles.csv`);
    run = r.ok ? 'read' : `status ${r.status}`;
  } catch {
    run = 'blocked';
  }
  return { ws, run };
}

async function origin() {
  const liveUrl = shot;
  // Another site: a page served from another port of this machine (another origin).
  const site = http.createServer((req, res) => {
    res.writeHead(200, { 'Content-Type': 'text/html' });
    res.end('<!doctype html><title>another site</title><p>another site</p>');
  });
  await new Promise((resolve) => site.listen(0, '127.0.0.1', resolve));
  // DNS rebinding: a name of another site that resolves to this machine (Chromium's resolver
  // told so), so the viewer is the same origin as that site's page.
  const browser = await launchChromium(['--host-resolver-rules=MAP rebind.test 127.0.0.1',
    '--no-proxy-server']);
  try {
    const page = await browser.newPage();
    await page.goto(`http://127.0.0.1:${site.address().port}/`);
    const cross = await page.evaluate(reachViewer, { live: liveUrl, replay: url });
    log('from another site\'s page', JSON.stringify(cross));
    assert.deepEqual(cross, { ws: 'refused', run: 'blocked' });
    const rebound = (u) => u.replace('127.0.0.1', 'rebind.test');
    const first = await page.goto(rebound(url));
    assert.equal(first.status(), 403, 'the viewer refuses a page of another name');
    const same = await page.evaluate(reachViewer, { live: rebound(liveUrl), replay: rebound(url) });
    log('from a rebound name', JSON.stringify(same));
    assert.deepEqual(same, { ws: 'refused', run: 'status 403' });
  } finally {
    await browser.close();
    site.close();
  }
  // The viewer's own pages still work: the replay loads its run, the live page its stream.
  const replay = await openViewer(url);
  try {
    assert.ok(await replay.page.evaluate(() => window.syndds.frames) > 0, 'the run is loaded');
    // Its own run file; the live viewer, on another port, is another site to it.
    const own = await replay.page.evaluate(reachViewer, { live: liveUrl, replay: url });
    log('from the replay page', JSON.stringify(own));
    assert.deepEqual(own, { ws: 'refused', run: 'read' });
  } finally {
    await replay.browser.close();
  }
  const live = await openViewer(liveUrl);
  try {
    await live.page.waitForFunction(() => window.syndds.updates > 0, null, { timeout: 60000 });
    log('the live page gets updates');
  } finally {
    await live.browser.close();
  }
}

// Two HMMWVs driven head-on (tests/multiprocess/scenarios/vehicle_contact_head_on.yaml): each
// vehicle's collision with the other is a red mark at the contact point, shown from its frame on.
async function contact() {
  const { browser, page } = await openViewer(url);
  try {
    const frames = await page.evaluate(() => window.syndds.frames);
    const marks = await page.evaluate(() => window.syndds.contactMarks);
    log(`${marks} contact marks`);
    assert.equal(marks, 2, 'a mark for each vehicle of the head-on');
    await moveSlider(page, 0);
    assert.equal(await page.evaluate(() => window.syndds.visibleContactMarks()), 0,
                 'no mark before the contact');
    await moveSlider(page, frames - 1);
    assert.equal(await page.evaluate(() => window.syndds.visibleContactMarks()), 2,
                 'both marks after it');
    await page.evaluate(() => { window.syndds.select('a'); window.syndds.setView('follow'); });
    await page.screenshot({ path: shot });
  } finally {
    await browser.close();
  }
}

const cases = { replay, ruts, live, watch, origin, contact };
if (!cases[kind]) { console.error(`unknown case ${kind}`); process.exit(1); }
cases[kind]().then(() => log('passed'), (e) => { console.error(`browser_tests ${kind}: FAILED: ${e.message}`); process.exit(1); });
