// The viewer in a real headless browser (Debian's chromium through playwright-core): one case
// per invocation, run by tests/viewer/browser_tests.sh, which starts the programs.
//   node browser_tests.mjs replay URL SHOT.png        default scenario, recorded
//   node browser_tests.mjs ruts URL SHOT.png          scm_crossing, recorded
//   node browser_tests.mjs contact URL SHOT.png       a recorded head-on: its contact marks
//   node browser_tests.mjs radar URL SHOT.png BAD_URL a recorded radar (radar_scene.yaml): its
//                                                     detections; BAD_URL: the same run with a
//                                                     malformed radar.csv
//   node browser_tests.mjs live URL_FILE READY_FILE   a live scm_crossing run: Chromium starts
//                                                     first and writes READY_FILE, then opens
//                                                     the address the launcher writes to URL_FILE
//   node browser_tests.mjs radarlive URL RADAR.csv    a live radar_scene.yaml run: its radar's
//                                                     detections, as RADAR.csv records them
//   node browser_tests.mjs watch URL [sensors]        a live run: states arrive (with
//                                                     `sensors`: lead's camera and lidar too);
//                                                     then watches until killed
//   node browser_tests.mjs origin URL LIVE_URL        a replay viewer (URL) and a live one:
//                                                     other sites' pages cannot reach either
import assert from 'node:assert/strict';
import { readFileSync, writeFileSync } from 'node:fs';
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

// The text of file `path` once it is not empty (bounded wait).
async function fileText(path, timeoutMs = 60000) {
  for (const end = Date.now() + timeoutMs; Date.now() < end;) {
    try {
      const text = readFileSync(path, 'utf8').trim();
      if (text) return text;
    } catch { /* not there yet */ }
    await new Promise((r) => setTimeout(r, 100));
  }
  throw new Error(`${path} stayed empty for ${timeoutMs / 1000} s`);
}

async function live() {
  // Chromium is up before the run starts (on a loaded machine it takes many seconds): the page
  // has the run's whole 20 s.
  const chromium = await launchChromium();
  writeFileSync(shot, 'ready\n');
  const { browser, page } = await openViewer(await fileText(url), { browser: chromium });
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

// tests/viewer/radar_scene.yaml recorded: r's radar sees `away` driving off and `towards`
// coming at it. At each time the page draws the newest scan at or before it, in the 3-D view and
// the top-down panel; approaching and receding detections differ in colour (blue, red). A
// malformed radar.csv is named with its line, and the rest of the replay works.
async function radar() {
  const badUrl = process.argv[5];
  const { browser, page } = await openViewer(url);
  try {
    const scans = await page.evaluate(() => window.syndds.radarScans);
    log(`${scans} radar scans with detections`);
    assert.ok(scans > 40, 'radar.csv is read');
    const heartbeat = await page.evaluate(() => window.syndds.state.scene.heartbeat_s);
    for (const t of [1.5, 2.5, 3.5]) {
      await page.evaluate((s) => window.syndds.setTime(s), t);
      const r = await page.evaluate(() => window.syndds.radarDetections());
      const shownT = await page.evaluate(() => window.syndds.state.frame) * heartbeat;
      log(`at ${shownT.toFixed(2)} s:`, JSON.stringify(r.detections.map((d) =>
        [d.time_s, d.radial_speed_mps, d.colour])), `panel ${r.panel}`);
      assert.ok(r.drawn > 0 && r.drawn === r.detections.length, 'detections are drawn');
      assert.equal(r.panel, r.drawn, 'and dotted in the top-down panel');
      // The newest scan at or before the time shown: one scan of the 20 Hz radar.
      const times = new Set(r.detections.map((d) => d.time_s));
      assert.equal(times.size, 1, 'one scan of the one radar');
      const [scanT] = times;
      assert.ok(scanT <= shownT + 1e-9 && scanT > shownT - 0.05 - 1e-9, `scan at ${scanT} s is the newest`);
      const approaching = r.detections.filter((d) => d.radial_speed_mps < -1);
      const receding = r.detections.filter((d) => d.radial_speed_mps > 1);
      assert.ok(approaching.length > 0 && receding.length > 0, 'towards approaches, away recedes');
      const rgb = (c) => [1, 3, 5].map((k) => parseInt(c.slice(k, k + 2), 16));
      for (const d of approaching) {
        const [red, , blue] = rgb(d.colour);
        assert.ok(blue > red + 20, `approaching ${d.radial_speed_mps} m/s is blue: ${d.colour}`);
      }
      for (const d of receding) {
        const [red, , blue] = rgb(d.colour);
        assert.ok(red > blue + 20, `receding ${d.radial_speed_mps} m/s is red: ${d.colour}`);
      }
    }
    const legend = await page.textContent('#radar-legend');
    assert.match(legend, /-10 m\/s approaching.*\+10 m\/s receding/s, 'the legend names the scale');
    await page.evaluate(() => { window.syndds.select('r'); window.syndds.setView('follow'); window.syndds.setTime(2.5); });
    await page.screenshot({ path: shot });
  } finally {
    await browser.close();
  }
  const bad = await openViewer(badUrl);
  try {
    const s = await bad.page.evaluate(() => ({ warnings: window.syndds.warnings, frames: window.syndds.frames,
      drawn: window.syndds.radarDetections().drawn, shown: document.getElementById('error').textContent }));
    log('malformed radar.csv:', JSON.stringify(s.warnings));
    assert.equal(s.warnings.length, 1);
    assert.match(s.warnings[0], /radar\.csv line 3: world_y 'north' is not a number/);
    assert.ok(s.shown.includes(s.warnings[0]), 'the page shows it');
    assert.equal(s.drawn, 0, 'no detections drawn from it');
    assert.ok(s.frames > 100, 'the replay itself works');
  } finally {
    await bad.browser.close();
  }
}

// tests/viewer/radar_scene.yaml run distributed with a live viewer, the page opened after the
// run ended: it draws r's newest radar scan, each detection at the world position, with the
// radial speed, that the recorder writes to radar.csv.
async function radarlive() {
  const csvPath = shot;
  const { browser, page } = await openViewer(url);
  let seen;
  try {
    await page.waitForFunction(() => window.syndds.radarDetections().drawn > 0, null, { timeout: 60000 });
    seen = await page.evaluate(() => window.syndds.radarDetections());
  } finally {
    await browser.close();
  }
  const t = seen.detections[0].time_s;
  log(`${seen.drawn} detections of the scan at ${t} s:`,
    JSON.stringify(seen.detections.map((d) => [d.at.map((x) => +x.toFixed(3)), +d.radial_speed_mps.toFixed(3)])));
  assert.ok(seen.detections.every((d) => d.time_s === t), 'one scan');
  // The recorder commits a frame's rows after the frame: wait (bounded) for that scan's.
  let rows = [];
  for (let k = 0; k < 600 && rows.length < seen.drawn; ++k) {
    if (k > 0) await new Promise((r) => setTimeout(r, 100));
    let text = '';
    try { text = readFileSync(csvPath, 'utf8'); } catch { continue; }
    const lines = text.split('\n').filter((l) => l.length > 0).map((l) => l.split(','));
    const c = Object.fromEntries(lines[0].map((h, i) => [h, i]));
    rows = lines.slice(1).filter((r) => Number(r[c.time_s]) === t).map((r) => ({
      at: [+r[c.world_x], +r[c.world_y], +r[c.world_z]], speed: +r[c.radial_speed_mps] }));
  }
  assert.equal(rows.length, seen.drawn, `radar.csv has the scan at ${t} s with as many detections`);
  // The run ended before the page loaded: what it draws is the newest scan recorded.
  const times = readFileSync(csvPath, 'utf8').split('\n').slice(1).filter((l) => l.length > 0)
    .map((l) => Number(l.split(',')[4]));
  assert.equal(t, Math.max(...times), 'the newest scan of the run');
  seen.detections.forEach((d, k) => {
    for (let a = 0; a < 3; ++a) {
      assert.ok(Math.abs(d.at[a] - rows[k].at[a]) < 1e-3, `detection ${k} at ${d.at} as recorded (${rows[k].at})`);
    }
    assert.ok(Math.abs(d.radial_speed_mps - rows[k].speed) < 1e-3, `detection ${k}'s radial speed as recorded`);
  });
}

const cases = { replay, ruts, live, watch, origin, contact, radar, radarlive };
if (!cases[kind]) { console.error(`unknown case ${kind}`); process.exit(1); }
cases[kind]().then(() => log('passed'), (e) => { console.error(`browser_tests ${kind}: FAILED: ${e.message}`); process.exit(1); });
