// syndds viewer page (docs/viewer.md): draws a scene document (/api/scene) and either a recorded
// run (/run/*.csv, replay with a time slider) or a live run (WebSocket /live). World frame:
// x east, y north, z up (three.js is told that z is up).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { OBJLoader } from 'three/addons/loaders/OBJLoader.js';

const $ = (id) => document.getElementById(id);
const SOIL_TILE = 64;          // soil vertices per tile side (a mesh per deformed tile)
const RUT_COLOUR_MAX_M = 0.10; // depth at the end of the colour ramp
// Live pictures per second at most, and only when something changed: a browser drawing on the
// CPU (no GPU) competes with the simulation for the same cores (docs/performance.md, "Viewer").
const LIVE_FPS = 10;
const READOUT_HZ = 4;          // live panel text updates per second
const DRAW_BUDGET = 0.1;       // share of the wall time the live page may spend drawing

function fail(message) {
  $('error').style.display = 'block';
  $('error').textContent = message;
  window.syndds.error = message;
}
// A problem that leaves the rest of the page working (a run file it cannot use): shown in the
// error box, kept in window.syndds.warnings.
function warn(message) {
  window.syndds.warnings.push(message);
  $('error').style.display = 'block';
  $('error').textContent = window.syndds.warnings.join('\n');
}

// ---- CSV (as the recorder writes it: a header, RFC 4180 quotes on text cells) ----
function parseCsvLine(line) {
  if (line.indexOf('"') < 0) return line.split(',');
  const out = []; let cell = ''; let quoted = false;
  for (let k = 0; k < line.length; ++k) {
    const c = line[k];
    if (quoted) {
      if (c === '"' && line[k + 1] === '"') { cell += '"'; ++k; }
      else if (c === '"') quoted = false;
      else cell += c;
    } else if (c === '"') quoted = true;
    else if (c === ',') { out.push(cell); cell = ''; }
    else cell += c;
  }
  out.push(cell);
  return out;
}
function parseCsv(text) {
  const lines = text.split('\n').filter((l) => l.length > 0);
  const header = parseCsvLine(lines[0] || '');
  const col = Object.fromEntries(header.map((h, k) => [h, k]));
  return { col, rows: lines.slice(1).map(parseCsvLine) };
}
async function fetchText(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: ${r.status}`);
  return r.text();
}

// ---- world ----
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
$('view').appendChild(renderer.domElement);
const scene3 = new THREE.Scene();
scene3.background = new THREE.Color(0x9fb9d6);
const camera = new THREE.PerspectiveCamera(50, 1, 0.1, 5000);
camera.up.set(0, 0, 1);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = false;
scene3.add(new THREE.HemisphereLight(0xdfe8f5, 0x6b5a45, 1.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(0.5, -0.7, 1.0);
scene3.add(sun);

const state = {
  scene: null, mode: 'replay', frame: 0, vehicles: new Map(), selected: null, view: 'follow',
  soil: null, rtf: null, status: '-', members: [], dirty: true,
  meshes: new Map(), meshStats: { obstacles: 0, vehicles: 0 },
};
window.syndds = { ready: false, error: null, warnings: [], state, meshErrors: [] };

function colourOf(c) { return new THREE.Color(c[0], c[1], c[2]); }

// Contact marks: a sphere where a collision began, red between vehicles, orange on obstacles.
const contactMarks = new THREE.Group();
scene3.add(contactMarks);
const contactGeometry = new THREE.SphereGeometry(0.35, 12, 8);
const contactMaterials = {
  vehicle: new THREE.MeshBasicMaterial({ color: 0xff2020 }),
  obstacle: new THREE.MeshBasicMaterial({ color: 0xff9900 }),
};
window.syndds.contactMarks = 0;
window.syndds.visibleContactMarks = () => contactMarks.children.filter((m) => m.visible).length;
function addContactMark(at, vehicleContact) {
  const m = new THREE.Mesh(contactGeometry, vehicleContact ? contactMaterials.vehicle : contactMaterials.obstacle);
  m.position.set(at[0], at[1], at[2] + 0.3);
  contactMarks.add(m);
  window.syndds.contactMarks = contactMarks.children.length;
  state.dirty = true;
  return m;
}
// "vehicle=b impulse_ns=... at=x/y/z" (events.csv detail of a collision) -> {at, vehicleContact}.
function parseCollision(detail) {
  const at = /at=(-?[0-9.e+-]+)\/(-?[0-9.e+-]+)\/(-?[0-9.e+-]+)/.exec(detail);
  if (!at) return null;
  return { at: [+at[1], +at[2], +at[3]], vehicleContact: detail.startsWith('vehicle=') };
}

// Radar detections (docs/viewer.md, "Radar"): the newest scan of each radar (vehicle, sensor),
// a small sphere at each detection's world position in the 3-D view (ringed in black and drawn
// over the scene: a detection lies on a surface, half inside it) and a dot in the top-down
// panel, both coloured by the detection's radial speed on a diverging scale: approaching
// (negative) blue, receding (positive) red, 0 light grey, linear in between and clamped at
// +-RADAR_SPEED_MPS (the ends and middle of ColorBrewer's RdBu).
const RADAR_SPEED_MPS = 10;
const RADAR_APPROACHING = [0x21, 0x66, 0xac], RADAR_STILL = [0xf7, 0xf7, 0xf7];
const RADAR_RECEDING = [0xb2, 0x18, 0x2b];
function radarColour(speed) {
  const u = Math.max(-1, Math.min(1, speed / RADAR_SPEED_MPS));
  const end = u < 0 ? RADAR_APPROACHING : RADAR_RECEDING;
  const rgb = RADAR_STILL.map((x, k) => Math.round(x + (end[k] - x) * Math.abs(u)));
  return '#' + rgb.map((x) => x.toString(16).padStart(2, '0')).join('');
}
const radarGeometry = new THREE.SphereGeometry(0.3, 12, 8);
const radarRingGeometry = new THREE.SphereGeometry(0.4, 12, 8);
const radarMaterial = new THREE.MeshBasicMaterial({ color: 0xffffff, depthTest: false });
const radarRingMaterial = new THREE.MeshBasicMaterial({ color: 0x000000, depthTest: false });
const radarScans = new Map();  // 'vehicle/sensor' -> {vehicle, sensor, time, detections: [{at, speed, strength}]}
let radarMarks = null;         // one instance per detection drawn; replaced by a larger one as needed
let radarRings = null;         // the same, black and larger, drawn before radarMarks
let radarDrawn = [];           // the detections drawn, in instance order
function showRadar() {
  radarDrawn = [];
  for (const s of radarScans.values()) {
    for (const d of s.detections) {
      radarDrawn.push({ vehicle: s.vehicle, sensor: s.sensor, time_s: s.time, at: d.at,
        radial_speed_mps: d.speed, strength_db: d.strength, colour: radarColour(d.speed) });
    }
  }
  const n = radarDrawn.length;
  if (!radarMarks || radarMarks.instanceMatrix.count < n) {
    for (const o of [radarMarks, radarRings]) if (o) { scene3.remove(o); o.dispose(); }
    const capacity = Math.max(64, 2 * n);
    radarRings = new THREE.InstancedMesh(radarRingGeometry, radarRingMaterial, capacity);
    radarMarks = new THREE.InstancedMesh(radarGeometry, radarMaterial, capacity);
    radarMarks.instanceColor = new THREE.InstancedBufferAttribute(new Float32Array(3 * capacity), 3);
    radarRings.renderOrder = 1; radarMarks.renderOrder = 2;
    for (const o of [radarRings, radarMarks]) {
      o.frustumCulled = false;  // its bounds change with every scan
      scene3.add(o);
    }
  }
  const m = new THREE.Matrix4(), c = new THREE.Color();
  radarDrawn.forEach((d, k) => {
    m.makeTranslation(d.at[0], d.at[1], d.at[2]);
    radarMarks.setMatrixAt(k, m);
    radarRings.setMatrixAt(k, m);
    radarMarks.setColorAt(k, c.set(d.colour));
  });
  radarMarks.count = radarRings.count = n;
  radarMarks.instanceMatrix.needsUpdate = radarRings.instanceMatrix.needsUpdate = true;
  radarMarks.instanceColor.needsUpdate = true;
  $('radar-legend').style.display = 'block';
  state.dirty = true;
  drawTopDown();
}
// The detections drawn, for the tests: how many spheres the 3-D view has and the panel's dots,
// and each detection with the colour its sphere is drawn in.
window.syndds.radarDetections = () => {
  const c = new THREE.Color();
  return {
    drawn: radarMarks ? radarMarks.count : 0, panel: topDown.radarDots,
    detections: radarDrawn.map((d, k) => {
      radarMarks.getColorAt(k, c);
      return { ...d, colour: '#' + c.getHexString() };
    }),
  };
};

function buildTerrain(t, soil) {
  const g = new THREE.BufferGeometry();
  const pos = new Float32Array(t.nx * t.ny * 3);
  for (let r = 0; r < t.ny; ++r) {
    for (let c = 0; c < t.nx; ++c) {
      const k = r * t.nx + c;
      pos[3 * k] = t.x_min + (t.x_max - t.x_min) * c / (t.nx - 1);
      pos[3 * k + 1] = t.y_min + (t.y_max - t.y_min) * r / (t.ny - 1);
      // Soil scenes: the patch is drawn by the soil's own meshes; the ground beneath stays
      // out of sight below the deepest rut (it shows only beyond the patch).
      pos[3 * k + 2] = t.heights[k] - (soil ? 0.5 : 0);
    }
  }
  const idx = [];
  for (let r = 0; r + 1 < t.ny; ++r) {
    for (let c = 0; c + 1 < t.nx; ++c) {
      const a = r * t.nx + c, b = a + 1, d = a + t.nx, e = d + 1;
      idx.push(a, b, e, a, e, d);
    }
  }
  g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
  g.setIndex(idx);
  g.computeVertexNormals();
  const colour = soil ? 0x8a6a45 : 0x7d8a5f;
  // Pushed back so that the soil tiles drawn over it win where both are at the same height.
  const m = new THREE.MeshLambertMaterial({ color: colour, polygonOffset: true,
    polygonOffsetFactor: 2, polygonOffsetUnits: 2 });
  const mesh = new THREE.Mesh(g, m);
  scene3.add(mesh);
  // A grid every 10 m for scale.
  const grid = new THREE.GridHelper(Math.max(t.x_max - t.x_min, t.y_max - t.y_min),
    Math.round(Math.max(t.x_max - t.x_min, t.y_max - t.y_min) / 10), 0x555555, 0x777777);
  grid.rotation.x = Math.PI / 2;
  grid.position.set((t.x_min + t.x_max) / 2, (t.y_min + t.y_max) / 2, (t.heights[0] ?? 0) + 0.01);
  grid.material.transparent = true; grid.material.opacity = 0.25;
  if (t.nx === 2) scene3.add(grid);
}

// ---- deformable soil: a mesh at the soil's own spacing per tile that has deformed ----
class Soil {
  constructor(info) {
    this.d = info.spacing_m; this.base = info.base_height_m; this.info = info;
    this.tiles = new Map(); this.dirty = new Set(); this.values = new Map();
    this.material = new THREE.MeshLambertMaterial({ vertexColors: true });
    this.maxDepth = 0;
    this.buildCover();
  }
  // The undeformed soil: one flat quad per tile of the visible patch; a tile's quad is taken out
  // when the tile gets a mesh of its own (its ruts lie below the undeformed surface).
  buildCover() {
    const t = state.scene.terrain, span = SOIL_TILE * this.d, info = this.info;
    const lo = (v, m) => Math.floor(Math.max(v, m) / span), hi = (v, m) => Math.ceil(Math.min(v, m) / span) - 1;
    this.t0 = [lo(t.x_min, info.i_min * this.d), lo(t.y_min, info.j_min * this.d)];
    this.t1 = [hi(t.x_max, info.i_max * this.d), hi(t.y_max, info.j_max * this.d)];
    const nx = this.t1[0] - this.t0[0] + 1, ny = this.t1[1] - this.t0[1] + 1;
    if (nx <= 0 || ny <= 0) return;
    const pos = new Float32Array(nx * ny * 12);
    this.coverIndex = new Uint32Array(nx * ny * 6);
    for (let b = 0; b < ny; ++b) {
      for (let a = 0; a < nx; ++a) {
        const q = b * nx + a, x0 = (this.t0[0] + a) * span, y0 = (this.t0[1] + b) * span;
        pos.set([x0, y0, this.base, x0 + span, y0, this.base, x0 + span, y0 + span, this.base,
          x0, y0 + span, this.base], 12 * q);
        this.coverIndex.set([4 * q, 4 * q + 1, 4 * q + 2, 4 * q, 4 * q + 2, 4 * q + 3], 6 * q);
      }
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    g.setIndex(new THREE.BufferAttribute(this.coverIndex.slice(), 1));
    g.computeVertexNormals();
    this.cover = new THREE.Mesh(g, new THREE.MeshLambertMaterial({ color: 0x8a6a45 }));
    this.coverSize = [nx, ny];
    scene3.add(this.cover);
  }
  showCover(ti, tj, on) {
    if (!this.cover) return;
    const a = ti - this.t0[0], b = tj - this.t0[1];
    if (a < 0 || b < 0 || a >= this.coverSize[0] || b >= this.coverSize[1]) return;
    const q = b * this.coverSize[0] + a, idx = this.cover.geometry.index;
    for (let k = 0; k < 6; ++k) idx.array[6 * q + k] = on ? this.coverIndex[6 * q + k] : 0;
    idx.needsUpdate = true;
  }
  key(ti, tj) { return ti + ',' + tj; }
  tile(ti, tj) {
    const k = this.key(ti, tj);
    let t = this.tiles.get(k);
    if (t) return t;
    const n = SOIL_TILE + 1;
    const pos = new Float32Array(n * n * 3), col = new Float32Array(n * n * 3);
    for (let b = 0; b < n; ++b) {
      for (let a = 0; a < n; ++a) {
        const v = b * n + a, i = ti * SOIL_TILE + a, j = tj * SOIL_TILE + b;
        pos[3 * v] = i * this.d; pos[3 * v + 1] = j * this.d;
        pos[3 * v + 2] = this.values.get(i + ',' + j) ?? this.base;
        this.paint(col, v, this.base - pos[3 * v + 2]);
      }
    }
    const idx = [];
    for (let b = 0; b < SOIL_TILE; ++b) {
      for (let a = 0; a < SOIL_TILE; ++a) {
        const p = b * n + a, q = p + 1, r = p + n, s = r + 1;
        idx.push(p, q, s, p, s, r);
      }
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    g.setAttribute('color', new THREE.BufferAttribute(col, 3));
    g.setIndex(idx);
    g.computeVertexNormals();
    t = { mesh: new THREE.Mesh(g, this.material), ti, tj };
    scene3.add(t.mesh);
    this.showCover(ti, tj, false);
    this.tiles.set(k, t);
    return t;
  }
  paint(col, v, depth) {
    // Undisturbed soil brown; deeper ruts orange, red, then dark purple; raised rims lighter.
    const stops = [[0.54, 0.42, 0.27], [0.79, 0.49, 0.17], [0.71, 0.17, 0.17], [0.23, 0.08, 0.31]];
    let c;
    if (depth <= 0) {
      const u = Math.min(1, -depth / 0.05);
      c = stops[0].map((x) => x + (0.85 - x) * u * 0.6);
    } else {
      const u = Math.min(1, depth / RUT_COLOUR_MAX_M) * 3;
      const k = Math.min(2, Math.floor(u)), f = u - k;
      c = stops[k].map((x, n) => x + (stops[k + 1][n] - x) * f);
    }
    // The stops are sRGB (as the base colour 0x8a6a45 is); vertex colours are linear.
    col[3 * v] = c[0] ** 2.2; col[3 * v + 1] = c[1] ** 2.2; col[3 * v + 2] = c[2] ** 2.2;
  }
  set(i, j, h) {
    this.values.set(i + ',' + j, h);
    this.maxDepth = Math.max(this.maxDepth, this.base - h);
    const ti = Math.floor(i / SOIL_TILE), tj = Math.floor(j / SOIL_TILE);
    // A vertex on a tile's edge belongs to the neighbours too.
    for (const [a, b] of [[ti, tj], [ti - 1, tj], [ti, tj - 1], [ti - 1, tj - 1]]) {
      const li = i - a * SOIL_TILE, lj = j - b * SOIL_TILE;
      if (li < 0 || lj < 0 || li > SOIL_TILE || lj > SOIL_TILE) continue;
      if ((a !== ti || b !== tj) && !this.tiles.has(this.key(a, b))) continue;
      const t = this.tile(a, b);
      const v = lj * (SOIL_TILE + 1) + li;
      const g = t.mesh.geometry;
      g.attributes.position.array[3 * v + 2] = h;
      this.paint(g.attributes.color.array, v, this.base - h);
      this.dirty.add(t);
    }
  }
  reset() {
    for (const t of this.tiles.values()) {
      scene3.remove(t.mesh); t.mesh.geometry.dispose(); this.showCover(t.ti, t.tj, true);
    }
    this.tiles.clear(); this.dirty.clear(); this.values.clear(); this.maxDepth = 0;
  }
  flush() {
    for (const t of this.dirty) {
      const g = t.mesh.geometry;
      g.attributes.position.needsUpdate = true;
      g.attributes.color.needsUpdate = true;
      g.computeVertexNormals();
      g.computeBoundingSphere();
    }
    this.dirty.clear();
  }
}

// ---- meshes (/meshes/*.obj: the files the sensors draw with, docs/sensors.md "Meshes") ----
// Materials by name from meshes.mtl (its Kd colours), read here so that mesh colours are treated
// like every other colour of the scene document.
async function loadMeshes(names) {
  const meshes = new Map();
  if (!names || names.length === 0) return meshes;
  const colours = new Map();
  let name = null;
  for (const line of (await fetchText('/meshes/meshes.mtl').catch(() => '')).split('\n')) {
    const w = line.trim().split(/\s+/);
    if (w[0] === 'newmtl') name = w[1];
    else if (w[0] === 'Kd' && name) colours.set(name, [+w[1], +w[2], +w[3]]);
  }
  const loader = new OBJLoader();
  for (const n of names) {
    try {
      const obj = loader.parse(await fetchText(`/meshes/${n}.obj`));
      const box = new THREE.Box3().setFromObject(obj);
      if (box.isEmpty()) throw new Error('no triangles');
      meshes.set(n, { obj, box, colours });
    } catch (e) {
      window.syndds.meshErrors.push(`${n}.obj: ${e.message}`);
    }
  }
  return meshes;
}

// A copy of mesh `m` with its bounding box mapped onto [lo, hi] axis by axis (as the sensors'
// fit_to_box does); material `body` in `bodyColour` when given, the others in their MTL colour.
function fittedMesh(m, lo, hi, bodyColour) {
  const inner = m.obj.clone();
  const size = m.box.getSize(new THREE.Vector3());
  const scale = new THREE.Vector3(...[0, 1, 2].map((k) =>
    size.getComponent(k) > 0 ? (hi[k] - lo[k]) / size.getComponent(k) : 1));
  inner.scale.copy(scale);
  inner.position.set(...[0, 1, 2].map((k) => lo[k] - m.box.min.getComponent(k) * scale.getComponent(k)));
  const material = (old) => {
    const c = old.name === 'body' && bodyColour ? bodyColour
      : m.colours.has(old.name) ? colourOf(m.colours.get(old.name)) : new THREE.Color(0.5, 0.5, 0.5);
    return new THREE.MeshLambertMaterial({ color: c, side: THREE.DoubleSide });
  };
  inner.traverse((o) => {
    if (o.isMesh) o.material = Array.isArray(o.material) ? o.material.map(material) : material(o.material);
  });
  const outer = new THREE.Group();
  outer.add(inner);
  return outer;
}

function buildObstacle(o) {
  let m;
  const mesh = state.meshes.get(o.label);
  if (mesh) {
    const r = o.size[0];
    const half = o.shape === 'box' ? o.size : o.shape === 'sphere' ? [r, r, r] : [r, r, o.size[2]];
    m = fittedMesh(mesh, half.map((h) => -h), half);
    ++state.meshStats.obstacles;
  } else {
    let g;
    if (o.shape === 'sphere') g = new THREE.SphereGeometry(o.size[0], 24, 16);
    else if (o.shape === 'cylinder') {
      g = new THREE.CylinderGeometry(o.size[0], o.size[0], 2 * o.size[2], 24);
      g.rotateX(Math.PI / 2);  // three's cylinders stand on y; ours on their local z
    } else g = new THREE.BoxGeometry(2 * o.size[0], 2 * o.size[1], 2 * o.size[2]);
    m = new THREE.Mesh(g, new THREE.MeshLambertMaterial({ color: colourOf(o.colour) }));
  }
  m.position.set(...o.position);
  m.quaternion.set(o.orientation[1], o.orientation[2], o.orientation[3], o.orientation[0]);
  scene3.add(m);
}

function groundAt(x, y) {
  const t = state.scene.terrain;
  const c = Math.min(t.nx - 1, Math.max(0, Math.round((x - t.x_min) / (t.x_max - t.x_min) * (t.nx - 1))));
  const r = Math.min(t.ny - 1, Math.max(0, Math.round((y - t.y_min) / (t.y_max - t.y_min) * (t.ny - 1))));
  return t.heights[r * t.nx + c];
}

function buildVehicle(v) {
  const colour = colourOf(v.colour);
  const body = new THREE.Group();
  const material = new THREE.MeshLambertMaterial({ color: colour });
  const mesh = state.meshes.get('vehicle_body');
  if (v.body_boxes && mesh) {
    // The body mesh fitted to the boxes' bounding box, as the sensors draw it.
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (const b of v.body_boxes) {
      for (let k = 0; k < 3; ++k) {
        lo[k] = Math.min(lo[k], b.centre[k] - b.half_extents[k]);
        hi[k] = Math.max(hi[k], b.centre[k] + b.half_extents[k]);
      }
    }
    body.add(fittedMesh(mesh, lo, hi, colour));
    ++state.meshStats.vehicles;
  } else if (v.body_boxes) {
    // Hull between the wheels, deck above them, cabin: the sensors' boxes.
    for (const b of v.body_boxes) {
      const m = new THREE.Mesh(new THREE.BoxGeometry(...b.half_extents.map((h) => 2 * h)), material);
      m.position.set(...b.centre);
      body.add(m);
    }
  } else {
    // A scene document without body boxes (older recorder): the body between the wheels.
    const he = v.chassis_half_extents, c = v.chassis_centre;
    const halfTrack = Math.min(...v.wheel_positions.map((w) => Math.abs(w[1])));
    const halfWidth = Math.max(0.3, Math.min(he[1], halfTrack - 0.5 * v.wheel_width - 0.05));
    const top = c[2] + he[2], bottom = Math.min(top - 0.3, Math.max(c[2] - he[2], 0.1 * v.wheel_radius));
    const box = new THREE.Mesh(new THREE.BoxGeometry(2 * he[0], 2 * halfWidth, top - bottom), material);
    box.position.set(c[0], c[1], (top + bottom) / 2);
    body.add(box);
  }
  scene3.add(body);
  const wheels = [];
  for (let k = 0; k < 4; ++k) {
    const w = new THREE.Group();
    const tire = new THREE.Mesh(new THREE.CylinderGeometry(v.wheel_radius, v.wheel_radius, v.wheel_width, 24),
      new THREE.MeshLambertMaterial({ color: 0x202020 }));
    w.add(tire);
    // A light spoke, so that a spinning wheel is seen to spin.
    const spoke = new THREE.Mesh(new THREE.BoxGeometry(1.6 * v.wheel_radius, v.wheel_width * 1.02, 0.12 * v.wheel_radius),
      new THREE.MeshLambertMaterial({ color: 0xbbbbbb }));
    w.add(spoke);
    scene3.add(w);
    wheels.push(w);
  }
  // Planned path (dashed) and driven track.
  if (v.path.length > 1) {
    const pts = v.path.map((p) => new THREE.Vector3(p[0], p[1], groundAt(p[0], p[1]) + 0.15));
    if (v.path_closed) pts.push(pts[0].clone());
    const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(pts),
      new THREE.LineDashedMaterial({ color: colour, dashSize: 1.0, gapSize: 0.7 }));
    line.computeLineDistances();
    scene3.add(line);
  }
  const trackGeom = new THREE.BufferGeometry();
  const track = new THREE.Line(trackGeom, new THREE.LineBasicMaterial({ color: colour.clone().multiplyScalar(0.6) }));
  scene3.add(track);
  return { info: v, body, wheels, track: new Track(track), s: null };
}

function poseTo(obj, p) {
  obj.position.set(p[0], p[1], p[2]);
  obj.quaternion.set(p[4], p[5], p[6], p[3]);
}

// A vehicle's state: pose [x y z qw qx qy qz], wheels [[x y z qw qx qy qz spin] x4] or null.
function showVehicle(id, s) {
  const v = state.vehicles.get(id);
  if (!v) return;
  v.s = s;
  poseTo(v.body, s.pose);
  for (let k = 0; k < 4; ++k) {
    if (s.wheels && s.wheels[k]) poseTo(v.wheels[k], s.wheels[k]);
    else {
      // Without recorded wheel poses: at their places on the chassis.
      const local = new THREE.Vector3(...v.info.wheel_positions[k]).applyQuaternion(v.body.quaternion);
      v.wheels[k].position.copy(v.body.position).add(local);
      v.wheels[k].quaternion.copy(v.body.quaternion);
    }
  }
}

// A driven track: one growing vertex buffer per vehicle, drawn up to a count (no new geometry
// per update: a long run has hundreds of thousands of points).
class Track {
  constructor(line) {
    this.line = line; this.n = 0; this.array = new Float32Array(0);
    line.frustumCulled = false;  // its bounds change with every point
  }
  setAll(xyz) {
    this.array = xyz; this.n = xyz.length / 3;
    this.line.geometry.dispose();
    this.line.geometry = new THREE.BufferGeometry();
    this.line.geometry.setAttribute('position', new THREE.BufferAttribute(xyz, 3));
    this.line.geometry.setDrawRange(0, 0);
  }
  push(x, y, z) {
    const k = 3 * this.n;
    // A vehicle standing still adds no point.
    if (this.n > 0 && Math.hypot(x - this.array[k - 3], y - this.array[k - 2]) < 0.05) return;
    if (k + 3 > this.array.length) {
      const grown = new Float32Array(Math.max(3072, 2 * this.array.length));
      grown.set(this.array.subarray(0, k));
      const n = this.n;
      this.setAll(grown);
      this.n = n;
    }
    this.array[k] = x; this.array[k + 1] = y; this.array[k + 2] = z;
    ++this.n;
    const attr = this.line.geometry.getAttribute('position');
    attr.needsUpdate = true;
    this.show(this.n);
  }
  show(count) { this.line.geometry.setDrawRange(0, count); }
}

// ---- camera, panel ----
function resize() {
  const el = $('view');
  renderer.setSize(el.clientWidth, el.clientHeight);
  camera.aspect = el.clientWidth / Math.max(1, el.clientHeight);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);

function setView(mode) {
  state.view = mode;
  for (const b of ['follow', 'orbit', 'top']) $(b).classList.toggle('on', b === mode);
  const t = state.scene.terrain;
  if (mode === 'top') {
    // Straight down on everything the vehicles drive: their paths, tracks and positions.
    const box = new THREE.Box3();
    for (const v of state.vehicles.values()) {
      box.expandByPoint(v.body.position);
      for (const p of v.info.path) box.expandByPoint(new THREE.Vector3(p[0], p[1], 0));
      const a = v.track.array, n = v.track.line.geometry.drawRange.count;
      for (let k = 0; k < Math.min(n, v.track.n); ++k) box.expandByPoint(new THREE.Vector3(a[3 * k], a[3 * k + 1], 0));
    }
    if (box.isEmpty()) box.set(new THREE.Vector3(t.x_min, t.y_min, 0), new THREE.Vector3(t.x_max, t.y_max, 0));
    box.expandByScalar(8);
    const cx = (box.min.x + box.max.x) / 2, cy = (box.min.y + box.max.y) / 2;
    const half = Math.max((box.max.x - box.min.x) / camera.aspect, box.max.y - box.min.y) / 2;
    camera.position.set(cx, cy - 0.01, half / Math.tan(THREE.MathUtils.degToRad(camera.fov / 2)));
    controls.target.set(cx, cy, 0);
  } else if (mode === 'orbit') {
    const v = state.vehicles.get(state.selected);
    const c = v ? v.body.position : new THREE.Vector3();
    controls.target.copy(c);
    camera.position.set(c.x - 25, c.y - 25, c.z + 20);
  }
  controls.update();
}

function followCamera() {
  const v = state.vehicles.get(state.selected);
  if (!v || state.view !== 'follow') return;
  const back = new THREE.Vector3(-11, 0, 4.5).applyQuaternion(new THREE.Quaternion().setFromAxisAngle(
    new THREE.Vector3(0, 0, 1), headingOf(v.body.quaternion)));
  camera.position.copy(v.body.position).add(back);
  controls.target.copy(v.body.position).add(new THREE.Vector3(0, 0, 1));
  camera.lookAt(controls.target);
}

function headingOf(q) {
  const fwd = new THREE.Vector3(1, 0, 0).applyQuaternion(q);
  return Math.atan2(fwd.y, fwd.x);
}

function readout() {
  const v = state.vehicles.get(state.selected);
  const s = v && v.s;
  const sc = state.scene;
  $('r-time').textContent = `${(state.frame * sc.heartbeat_s).toFixed(2)} / ${sc.end_time_s.toFixed(1)} s (frame ${state.frame})`;
  $('progress-bar').style.width = `${Math.min(100, 100 * state.frame / Math.max(1, sc.final_frame))}%`;
  if (s) {
    $('r-speed').textContent = `${s.speed.toFixed(2)} m/s (${(s.speed * 3.6).toFixed(1)} km/h)`;
    $('r-gear').textContent = `${s.gear} / ${Math.round(s.rpm)} rpm`;
    $('r-inputs').textContent = `${s.steering.toFixed(2)} / ${s.throttle.toFixed(2)} / ${s.braking.toFixed(2)}`;
  }
  $('r-rtf').textContent = state.rtf == null ? '-' : `${state.rtf.toFixed(2)} (wall / sim)`;
  $('r-status').textContent = state.status;
  if (state.soil) $('legend-max').textContent = RUT_COLOUR_MAX_M.toFixed(2);
}

function render() {
  state.dirty = false;
  followCamera();
  if (state.view !== 'follow') controls.update();
  if (state.soil) state.soil.flush();
  renderer.render(scene3, camera);
}

// Screen position (CSS pixels in the view) of each vehicle: what the tests check.
function vehicleScreenPositions() {
  const out = {};
  const w = renderer.domElement.clientWidth, h = renderer.domElement.clientHeight;
  for (const [id, v] of state.vehicles) {
    const p = v.body.position.clone().project(camera);
    out[id] = [(p.x + 1) / 2 * w, (1 - p.y) / 2 * h];
  }
  return out;
}

// ---- replay ----
// radar.csv (one row per detection) as {'vehicle/sensor' -> {vehicle, sensor, scans, period}}:
// scans [{sequence, time, detections: [{at, speed, strength}]}] in time order, `period` the time
// from one scan to the next (sequence numbers count every scan, also the ones that detected
// nothing and so have no rows; Infinity from a single scan). Throws an Error naming the line of
// a missing column, a row of the wrong length or a cell that is not a number.
const RADAR_COLUMNS = ['vehicle', 'sensor', 'sequence', 'time_s', 'radial_speed_mps', 'strength_db',
  'world_x', 'world_y', 'world_z'];
function parseRadarCsv(text) {
  const lines = text.split('\n');
  const header = parseCsvLine(lines[0] || '');
  const col = Object.fromEntries(header.map((h, k) => [h, k]));
  for (const name of RADAR_COLUMNS) {
    if (col[name] === undefined) throw new Error(`radar.csv line 1: no column '${name}'`);
  }
  const sensors = new Map();
  for (let k = 1; k < lines.length; ++k) {
    if (lines[k].length === 0) continue;
    const r = parseCsvLine(lines[k]);
    if (r.length !== header.length) {
      throw new Error(`radar.csv line ${k + 1}: ${r.length} cells, the header has ${header.length}`);
    }
    const num = (name) => {
      const cell = r[col[name]], x = Number(cell);
      if (cell.trim() === '' || !Number.isFinite(x)) {
        throw new Error(`radar.csv line ${k + 1}: ${name} '${cell}' is not a number`);
      }
      return x;
    };
    const key = `${r[col.vehicle]}/${r[col.sensor]}`;
    let s = sensors.get(key);
    if (!s) sensors.set(key, s = { vehicle: r[col.vehicle], sensor: r[col.sensor], scans: [], period: Infinity });
    const sequence = num('sequence'), time = num('time_s');
    let scan = s.scans[s.scans.length - 1];
    if (!scan || scan.sequence !== sequence) s.scans.push(scan = { sequence, time, detections: [] });
    scan.detections.push({ at: [num('world_x'), num('world_y'), num('world_z')],
      speed: num('radial_speed_mps'), strength: num('strength_db') });
  }
  for (const s of sensors.values()) {
    s.scans.sort((a, b) => a.time - b.time);
    for (let k = 1; k < s.scans.length; ++k) {
      const dt = s.scans[k].time - s.scans[k - 1].time, dn = s.scans[k].sequence - s.scans[k - 1].sequence;
      if (dt > 0 && dn > 0) s.period = Math.min(s.period, dt / dn);
    }
  }
  return sensors;
}
// The scan of radar `s` shown at time t: the newest at or before t, unless a scan that detected
// nothing (no rows) came after it.
function newestScan(s, t) {
  let lo = 0, hi = s.scans.length;  // the first scan after t
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (s.scans[mid].time <= t + 1e-9) lo = mid + 1; else hi = mid;
  }
  const scan = s.scans[lo - 1];
  return scan && t < scan.time + s.period - 1e-9 ? scan : null;
}

async function startReplay(info) {
  const files = new Set(info.run_files || []);
  const vcsv = parseCsv(await fetchText('/run/vehicles.csv'));
  const c = vcsv.col;
  const frames = [];  // per frame index: Map vehicle -> state
  const frameIndex = new Map();
  for (const r of vcsv.rows) {
    const f = +r[c.frame];
    let k = frameIndex.get(f);
    if (k === undefined) { k = frames.length; frameIndex.set(f, k); frames.push({ frame: f, v: new Map() }); }
    frames[k].v.set(r[c.vehicle], {
      pose: [+r[c.x], +r[c.y], +r[c.z], +r[c.qw], +r[c.qx], +r[c.qy], +r[c.qz]], wheels: null,
      speed: +r[c.speed_mps], steering: +r[c.steering], throttle: +r[c.throttle],
      braking: +r[c.braking], gear: +r[c.gear], rpm: +r[c.engine_speed_rpm],
    });
  }
  if (files.has('wheels.csv')) {
    const w = parseCsv(await fetchText('/run/wheels.csv'));
    const d = w.col;
    for (const r of w.rows) {
      const k = frameIndex.get(+r[d.frame]);
      const s = k === undefined ? null : frames[k].v.get(r[d.vehicle]);
      if (!s) continue;
      if (!s.wheels) s.wheels = [];
      s.wheels[+r[d.wheel]] = [+r[d.x], +r[d.y], +r[d.z], +r[d.qw], +r[d.qx], +r[d.qy], +r[d.qz], +r[d.spin_rad_s]];
    }
  }
  // Soil snapshots: [{frame, i: Int32Array, j, h: Float64Array}] in frame order.
  const snapshots = [];
  if (state.soil && files.has('terrain_changes.csv')) {
    const t = parseCsv(await fetchText('/run/terrain_changes.csv'));
    const d = t.col;
    let cur = null;
    for (const r of t.rows) {
      const f = +r[d.frame];
      if (!cur || cur.frame !== f) { cur = { frame: f, i: [], j: [], h: [] }; snapshots.push(cur); }
      cur.i.push(+r[d.i]); cur.j.push(+r[d.j]); cur.h.push(+r[d.height]);
    }
  }
  // Camera frames saved by a sensor process: sensors/<vehicle>/frames.csv.
  const cameraFrames = new Map();
  for (const id of state.vehicles.keys()) {
    try {
      const t = parseCsv(await fetchText(`/run/sensors/${encodeURIComponent(id)}/frames.csv`));
      const d = t.col;
      cameraFrames.set(id, t.rows.filter((r) => r[d.file].endsWith('.png'))
        .map((r) => ({ time: +r[d.time_s], file: r[d.file], sensor: r[d.sensor] })));
    } catch (e) { /* no saved frames for this vehicle */ }
  }
  // Tracks: every recorded position, drawn up to the current frame (upTo[k]: the points of
  // frames 0..k, as a vehicle may be missing from some frames).
  const tracks = new Map();
  for (const [id, v] of state.vehicles) {
    const xyz = [], upTo = new Int32Array(frames.length);
    frames.forEach((fr, k) => {
      const s = fr.v.get(id);
      if (s) xyz.push(s.pose[0], s.pose[1], s.pose[2] + 0.05);
      upTo[k] = xyz.length / 3;
    });
    v.track.setAll(new Float32Array(xyz));
    tracks.set(id, upTo);
  }
  // Collisions (events.csv): each mark shown from its frame on.
  const collisionMarks = [];
  if (files.has('events.csv')) {
    const e = parseCsv(await fetchText('/run/events.csv'));
    const d = e.col;
    for (const r of e.rows) {
      if (r[d.kind] !== 'collision') continue;
      const c = parseCollision(r[d.detail] || '');
      if (c) { const m = addContactMark(c.at, c.vehicleContact); m.userData.frame = +r[d.frame]; collisionMarks.push(m); }
    }
  }
  // Radar detections (radar.csv): each radar's newest scan at or before the time shown.
  let radarSensors = null;
  if (files.has('radar.csv')) {
    try {
      radarSensors = parseRadarCsv(await fetchText('/run/radar.csv'));
    } catch (e) {
      warn(`viewer: ${e.message}; radar detections not shown`);
    }
  }
  window.syndds.radarScans = radarSensors
    ? [...radarSensors.values()].reduce((n, s) => n + s.scans.length, 0) : 0;
  let applied = -1;  // soil snapshots applied up to this frame
  let snapIndex = 0;
  const slider = $('slider');
  slider.max = Math.max(0, frames.length - 1);
  function show(k) {
    k = Math.max(0, Math.min(frames.length - 1, k | 0));
    const fr = frames[k];
    if (!fr) return;
    state.frame = fr.frame;
    for (const [id, s] of fr.v) showVehicle(id, s);
    for (const [id, v] of state.vehicles) v.track.show(tracks.get(id)[k]);
    for (const m of collisionMarks) m.visible = m.userData.frame <= fr.frame;
    if (radarSensors) {
      const t = fr.frame * state.scene.heartbeat_s;
      radarScans.clear();
      for (const [key, s] of radarSensors) {
        const scan = newestScan(s, t);
        if (scan) radarScans.set(key, { vehicle: s.vehicle, sensor: s.sensor, time: scan.time, detections: scan.detections });
      }
      showRadar();
    }
    if (state.soil) {
      if (fr.frame < applied) { state.soil.reset(); applied = -1; snapIndex = 0; }
      while (snapIndex < snapshots.length && snapshots[snapIndex].frame <= fr.frame) {
        const s = snapshots[snapIndex++];
        for (let n = 0; n < s.i.length; ++n) state.soil.set(s.i[n], s.j[n], s.h[n]);
      }
      applied = fr.frame;
    }
    const cams = cameraFrames.get(state.selected);
    if (cams && cams.length) {
      const t = fr.frame * state.scene.heartbeat_s;
      let best = null;
      for (const c of cams) { if (c.time <= t + 1e-9) best = c; else break; }
      const img = $('camera');
      if (best) {
        const src = `/run/sensors/${encodeURIComponent(state.selected)}/${best.file}`;
        if (img.getAttribute('src') !== src) img.src = src;
        img.style.display = 'block';
        $('camera-label').textContent = `${best.sensor} at ${best.time.toFixed(2)} s`;
      }
    } else { $('camera').style.display = 'none'; $('camera-label').textContent = ''; }
    slider.value = k;
    $('slider-time').textContent = `${(fr.frame * state.scene.heartbeat_s).toFixed(2)} s`;
    readout();
    render();
  }
  let playing = false, last = 0, pos = 0;
  slider.addEventListener('input', () => { pos = +slider.value; show(pos); });
  $('play').addEventListener('click', () => {
    playing = !playing; $('play').textContent = playing ? 'pause' : 'play'; last = performance.now();
  });
  function tick(now) {
    if (playing) {
      const dt = (now - last) / 1000; last = now;
      pos += dt * +$('speed').value / state.scene.heartbeat_s;
      if (pos >= frames.length - 1) { pos = frames.length - 1; playing = false; $('play').textContent = 'play'; }
      show(Math.floor(pos));
    } else if (state.dirty) render();
    requestAnimationFrame(tick);
  }
  try {
    const s = JSON.parse(await fetchText('/run/summary.json'));
    state.rtf = s.real_time_factor ?? null;
    state.status = s.status + (s.reason ? `: ${s.reason}` : '');
  } catch (e) { state.status = 'no summary'; }
  window.syndds.frames = frames.length;
  window.syndds.setFrameIndex = (k) => { pos = k; show(k); };
  window.syndds.setTime = (t) => {
    const k = Number.isFinite(t) ? Math.round(t / state.scene.heartbeat_s) : frames.length - 1;
    pos = Math.max(0, Math.min(frames.length - 1, k));
    show(pos);
  };
  window.syndds.snapshots = snapshots.length;
  show(0);
  requestAnimationFrame(tick);
}

// ---- live ----
function startLive() {
  $('timeline').style.display = 'none';
  $('view').style.bottom = '0'; $('panel').style.bottom = '0';
  resize();
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/live`;
  const ws = new WebSocket(url);
  ws.binaryType = 'blob';
  window.syndds.updates = 0;
  const lidarPoints = new THREE.Points(new THREE.BufferGeometry(),
    new THREE.PointsMaterial({ color: 0x00e0ff, size: 0.12 }));
  scene3.add(lidarPoints);
  const select = () => { if (ws.readyState === 1) ws.send(JSON.stringify({ select: state.selected })); };
  ws.onopen = select;
  $('vehicle').addEventListener('change', select);
  ws.onclose = () => { state.status += ' (viewer disconnected)'; readout(); };
  // Images received, and images decoded and shown (a JPEG decodes after it arrived; the next
  // one may replace it before, so the two counts differ on a busy machine).
  window.syndds.images = 0;
  window.syndds.imagesShown = 0;
  $('camera').onload = (ev) => {
    window.syndds.imagesShown++;
    window.syndds.imageSize = [ev.target.naturalWidth, ev.target.naturalHeight];
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data !== 'string') {
      const img = $('camera');
      const old = img.src;
      img.src = URL.createObjectURL(ev.data);
      img.style.display = 'block';
      $('camera-label').textContent = `camera of ${state.selected}`;
      if (old.startsWith('blob:')) URL.revokeObjectURL(old);
      window.syndds.images++;
      return;
    }
    const m = JSON.parse(ev.data);
    if (m.type === 'points') {
      const p = new Float32Array(m.xyz);
      lidarPoints.geometry.dispose();
      lidarPoints.geometry = new THREE.BufferGeometry();
      lidarPoints.geometry.setAttribute('position', new THREE.BufferAttribute(p, 3));
      state.dirty = true;
      topDown.lidar = p;
      drawTopDown();
      window.syndds.pointClouds = (window.syndds.pointClouds || 0) + 1;
      return;
    }
    if (m.type !== 'update') return;
    window.syndds.updates++;
    if (m.vehicles.length || m.soil.length) state.dirty = true;  // else only the panel's text
    state.frame = Math.max(0, m.frame);
    state.rtf = m.real_time_factor;
    state.status = m.status + (m.reason ? `: ${m.reason}` : '');
    for (const u of m.vehicles) {
      const s = { pose: u.pose, wheels: u.wheels.length ? u.wheels : null, speed: u.speed_mps,
        steering: u.steering, throttle: u.throttle, braking: u.braking, gear: u.gear, rpm: u.engine_speed_rpm };
      showVehicle(u.id, s);
      const v = state.vehicles.get(u.id);
      if (v) v.track.push(u.pose[0], u.pose[1], u.pose[2] + 0.05);
    }
    if (state.soil) for (const [i, j, h] of m.soil) state.soil.set(i, j, h);
    for (const c of m.contacts || []) addContactMark(c.at, c.vehicle_contact);
    if (m.radar && m.radar.length) {
      for (const r of m.radar) {
        radarScans.set(`${r.vehicle}/${r.sensor}`, { vehicle: r.vehicle, sensor: r.sensor, time: r.time_s,
          detections: r.detections.map((d) => ({ at: d.at, speed: d.radial_speed_mps, strength: d.strength_db })) });
      }
      showRadar();
    }
    if (m.members) {
      state.members = m.members;
      $('members').textContent = 'members\n' + m.members.map((x) => `  ${x.id} (${x.host} ${x.pid})`).join('\n');
    }
    textDue = true;
  };
  // Pictures at most LIVE_FPS a second, and no more often than keeps drawing within
  // DRAW_BUDGET of the time: a picture that took 40 ms (software WebGL) waits 400 ms for the next.
  // The panel's text at most READOUT_HZ a second: each change repaints the page.
  let last = 0, cost = 0, textDue = false, lastText = 0;
  const gl = renderer.getContext();
  window.syndds.drawStats = { pictures: 0, meanMs: 0 };
  // A timer at 40 Hz decides; the page asks for no display-frame callbacks while it has nothing
  // to draw.
  function tick() {
    const now = performance.now();
    if (textDue && now - lastText >= 1000 / READOUT_HZ) { textDue = false; lastText = now; readout(); }
    if (state.dirty && now - last >= Math.max(1000 / LIVE_FPS, cost / DRAW_BUDGET)) {
      last = now;
      const t0 = performance.now();
      render();
      gl.finish();  // the picture's whole cost, also when the GPU (or SwiftShader) draws it
      const ms = performance.now() - t0;
      cost = cost === 0 ? ms : 0.7 * cost + 0.3 * ms;
      const d = window.syndds.drawStats;
      d.meanMs += (ms - d.meanMs) / ++d.pictures;
    }
  }
  setInterval(tick, 25);
}

// The top-down panel: the chosen vehicle's surroundings from above, its forward up: the live
// lidar points (cyan) and the radar detections drawn (in their radial-speed colours). It spans
// 30 m around the vehicle, more (to 200 m) when radar detections lie farther; hidden until it
// has something to show.
const topDown = { lidar: null, radarDots: 0 };
function drawTopDown() {
  const cv = $('lidar');
  if (!topDown.lidar && radarScans.size === 0) return;
  cv.style.display = 'block';
  const g = cv.getContext('2d');
  g.fillStyle = '#111'; g.fillRect(0, 0, cv.width, cv.height);
  topDown.radarDots = 0;
  const v = state.vehicles.get(state.selected);
  if (!v) return;
  const c = v.body.position, yaw = headingOf(v.body.quaternion);
  const cs = Math.cos(-yaw), sn = Math.sin(-yaw);
  let half = 30;
  for (const d of radarDrawn) half = Math.max(half, 1.1 * Math.hypot(d.at[0] - c.x, d.at[1] - c.y));
  half = Math.min(200, 10 * Math.ceil(half / 10));
  const scale = cv.width / (2 * half);
  const toPanel = (x, y) => {
    const dx = x - c.x, dy = y - c.y;
    const fx = cs * dx - sn * dy, fy = sn * dx + cs * dy;  // vehicle frame: x forward, y left
    return [cv.width / 2 - fy * scale, cv.height / 2 - fx * scale];
  };
  const p = topDown.lidar;
  if (p) {
    g.fillStyle = '#00e0ff';
    for (let k = 0; k < p.length; k += 3) {
      const [px, py] = toPanel(p[k], p[k + 1]);
      g.fillRect(px, py, 1.5, 1.5);
    }
  }
  for (const d of radarDrawn) {
    const [px, py] = toPanel(d.at[0], d.at[1]);
    if (px < 0 || py < 0 || px >= cv.width || py >= cv.height) continue;
    g.fillStyle = d.colour;
    g.beginPath(); g.arc(px, py, 3, 0, 2 * Math.PI); g.fill();
    ++topDown.radarDots;
  }
  g.fillStyle = '#fff'; g.fillRect(cv.width / 2 - 2, cv.height / 2 - 3, 4, 6);
  g.fillStyle = '#aaa'; g.font = '10px system-ui, sans-serif';
  g.fillText(`${half} m around ${state.selected}`, 4, cv.height - 5);
}

// ---- start ----
async function main() {
  const info = JSON.parse(await fetchText('/api/info'));
  const sc = JSON.parse(await fetchText('/api/scene'));
  if (sc.format !== 1) throw new Error(`scene format ${sc.format}: this page reads format 1`);
  state.scene = sc; state.mode = info.mode;
  $('mode').textContent = `${info.mode}: ${sc.name}`;
  state.meshes = await loadMeshes(info.meshes);
  buildTerrain(sc.terrain, sc.soil);
  if (sc.soil) state.soil = new Soil(sc.soil);
  else $('legend').style.display = 'none';
  for (const o of sc.obstacles) buildObstacle(o);
  const select = $('vehicle');
  for (const v of sc.vehicles) {
    state.vehicles.set(v.id, buildVehicle(v));
    const opt = document.createElement('option');
    opt.value = opt.textContent = v.id;
    select.appendChild(opt);
    showVehicle(v.id, { pose: [...v.start, 1, 0, 0, 0], wheels: null, speed: 0, steering: 0,
      throttle: 0, braking: 0, gear: 0, rpm: 0 });
  }
  state.selected = sc.vehicles.length ? sc.vehicles[0].id : null;
  select.addEventListener('change', () => {
    state.selected = select.value; state.dirty = true;
    if (state.view !== 'follow') setView(state.view);
    drawTopDown();
  });
  $('radar-scale').textContent =
    `-${RADAR_SPEED_MPS} m/s approaching (blue), 0 (grey), +${RADAR_SPEED_MPS} m/s receding (red), clamped`;
  for (const b of ['follow', 'orbit', 'top']) $(b).addEventListener('click', () => setView(b));
  controls.addEventListener('start', () => { if (state.view === 'follow') setView('orbit'); });
  controls.addEventListener('change', () => { state.dirty = true; });
  window.addEventListener('resize', () => { state.dirty = true; });
  resize();
  setView('follow');
  window.syndds.vehicleScreenPositions = vehicleScreenPositions;
  window.syndds.setView = setView;
  window.syndds.setTime = () => {};  // replay only (set in startReplay)
  window.syndds.redraw = () => { readout(); render(); };
  window.syndds.showVehicles = (on) => {
    for (const v of state.vehicles.values()) { v.body.visible = on; for (const w of v.wheels) w.visible = on; }
    render();
  };
  // Looks straight down at (x, y) from `height` metres (the free camera).
  window.syndds.lookDown = (x, y, height) => {
    setView('orbit');
    controls.target.set(x, y, 0);
    camera.position.set(x, y - 0.01, height);
    controls.update();
    render();
  };
  window.syndds.meshStats = () => ({ ...state.meshStats, errors: window.syndds.meshErrors });
  window.syndds.vehicleState = (id) => { const v = state.vehicles.get(id); return v && v.s; };
  // What the view shows, for the tests: the share of pixels that are not sky, how many distinct
  // colours there are, and the share of pixels that differ from the picture kept by keep=true.
  let kept = null;
  window.syndds.pictureStats = (keep = false) => {
    render();
    const src = renderer.domElement;
    const c = document.createElement('canvas');
    c.width = src.width; c.height = src.height;
    const g = c.getContext('2d');
    g.drawImage(src, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    const sky = [0x9f, 0xb9, 0xd6], colours = new Set();
    let notSky = 0, changed = 0;
    for (let k = 0; k < d.length; k += 4) {
      if (Math.abs(d[k] - sky[0]) + Math.abs(d[k + 1] - sky[1]) + Math.abs(d[k + 2] - sky[2]) > 12) ++notSky;
      colours.add((d[k] >> 3) << 10 | (d[k + 1] >> 3) << 5 | (d[k + 2] >> 3));
      if (kept && kept.length === d.length &&
          Math.abs(d[k] - kept[k]) + Math.abs(d[k + 1] - kept[k + 1]) + Math.abs(d[k + 2] - kept[k + 2]) > 24) ++changed;
    }
    const n = d.length / 4;
    const out = { notSky: notSky / n, colours: colours.size, changed: kept ? changed / n : null };
    if (keep) kept = d;
    return out;
  };
  window.syndds.select = (id) => { select.value = id; select.dispatchEvent(new Event('change')); };
  window.syndds.soilStats = () => state.soil
    ? { tiles: state.soil.tiles.size, vertices: state.soil.values.size, maxDepth: state.soil.maxDepth }
    : null;
  if (info.mode === 'live') startLive();
  else await startReplay(info);
  render();
  window.syndds.ready = true;
}

main().catch((e) => fail(`viewer: ${e.message}`));
