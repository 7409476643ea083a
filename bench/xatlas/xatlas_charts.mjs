#!/usr/bin/env node
// xatlas peer for the chartification benchmark.
//
// usage: node xatlas_charts.mjs MESH.obj [--resolution N] [--padding P]
//
// Reads the positions and faces of a Wavefront OBJ, runs xatlas (WASM, the
// Node build shipped in the npm package "xatlasjs") chart computation,
// parameterisation and packing, and prints one line of JSON on stdout.
// Diagnostics go to stderr; a bad file or bad arguments exit with status 1.

import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';

const PKG_NAME = 'xatlasjs';
const here = path.dirname(fileURLToPath(import.meta.url));
const require = createRequire(import.meta.url);

function fail(msg) {
  process.stderr.write(`xatlas_charts: ${msg}\n`);
  process.exit(1);
}

function usage() {
  return 'usage: node xatlas_charts.mjs MESH.obj [--resolution N] [--padding P]';
}

// ---------------------------------------------------------------- arguments

function parseArgs(argv) {
  const opts = { file: null, resolution: 4096, padding: 2 };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    let key = null, val = null;
    const m = /^--(resolution|padding)(?:=(.*))?$/.exec(a);
    if (m) {
      key = m[1];
      val = m[2] !== undefined ? m[2] : argv[++i];
      if (val === undefined) fail(`--${key} needs a value\n${usage()}`);
      if (!/^\d+$/.test(val)) fail(`--${key} must be a non-negative integer, got '${val}'`);
      const n = Number(val);
      if (key === 'resolution' && (n < 1 || n > 65536)) fail('--resolution must be in 1..65536');
      if (key === 'padding' && n > 1024) fail('--padding must be in 0..1024');
      opts[key] = n;
    } else if (a === '-h' || a === '--help') {
      process.stdout.write(usage() + '\n');
      process.exit(0);
    } else if (a.startsWith('-') && a !== '-') {
      fail(`unknown option '${a}'\n${usage()}`);
    } else if (opts.file === null) {
      opts.file = a;
    } else {
      fail(`more than one mesh given\n${usage()}`);
    }
  }
  if (opts.file === null) fail(`no mesh given\n${usage()}`);
  return opts;
}

// ---------------------------------------------------------------- OBJ

// Returns { positions: Float32Array (xyz), indices: Uint32Array (triangles) }.
// Polygons are fan-triangulated; negative (relative) indices are resolved
// against the vertices read so far. Texture and normal indices are ignored.
function readObj(file) {
  let text;
  try {
    text = fs.readFileSync(file, 'utf8');
  } catch (e) {
    fail(`cannot read '${file}': ${e.code || e.message}`);
  }
  const pos = [];
  const idx = [];
  let nv = 0;
  const lines = text.split(/\r?\n/);
  const face = [];
  for (let ln = 0; ln < lines.length; ln++) {
    const line = lines[ln];
    const c0 = line.charCodeAt(0);
    if (c0 !== 118 /* v */ && c0 !== 102 /* f */ && c0 !== 32 && c0 !== 9) continue;
    const t = line.trim().split(/\s+/);
    const where = () => `${file}:${ln + 1}`;
    if (t[0] === 'v') {
      if (t.length < 4) fail(`${where()}: vertex with fewer than 3 coordinates`);
      const x = Number(t[1]), y = Number(t[2]), z = Number(t[3]);
      if (!Number.isFinite(x) || !Number.isFinite(y) || !Number.isFinite(z))
        fail(`${where()}: bad vertex coordinates '${line.trim()}'`);
      pos.push(x, y, z);
      nv++;
    } else if (t[0] === 'f') {
      if (t.length < 4) fail(`${where()}: face with fewer than 3 corners`);
      face.length = 0;
      for (let k = 1; k < t.length; k++) {
        const s = t[k];
        const slash = s.indexOf('/');
        const vs = slash < 0 ? s : s.slice(0, slash);
        if (!/^-?\d+$/.test(vs)) fail(`${where()}: bad face corner '${s}'`);
        let vi = parseInt(vs, 10);
        if (vi < 0) vi = nv + vi; else vi = vi - 1;
        if (vi < 0 || vi >= nv) fail(`${where()}: vertex index ${vs} out of range (${nv} vertices so far)`);
        face.push(vi);
      }
      for (let k = 1; k + 1 < face.length; k++) idx.push(face[0], face[k], face[k + 1]);
    }
  }
  if (nv === 0) fail(`'${file}': no vertices ('v' lines) found`);
  if (idx.length === 0) fail(`'${file}': no faces ('f' lines) found`);
  return { positions: Float32Array.from(pos), indices: Uint32Array.from(idx) };
}

// ---------------------------------------------------------------- analysis

// Number of charts = connected components of the output triangles, joined
// through shared output vertices (xatlas splits vertices on chart borders,
// so no output vertex belongs to two charts).
function countCharts(index, vertexCount) {
  const parent = new Int32Array(vertexCount);
  for (let i = 0; i < vertexCount; i++) parent[i] = i;
  const find = (a) => {
    while (parent[a] !== a) { parent[a] = parent[parent[a]]; a = parent[a]; }
    return a;
  };
  const unite = (a, b) => { a = find(a); b = find(b); if (a !== b) parent[a] = b; };
  const used = new Uint8Array(vertexCount);
  for (let i = 0; i < index.length; i += 3) {
    const a = index[i], b = index[i + 1], c = index[i + 2];
    used[a] = used[b] = used[c] = 1;
    unite(a, b); unite(b, c);
  }
  let n = 0;
  for (let i = 0; i < vertexCount; i++) if (used[i] && find(i) === i) n++;
  return n;
}

// Fraction of the W x H texels whose centre lies inside (or on the edge of)
// at least one output uv triangle. uv is normalised to [0,1]^2.
function rasterUtilisation(uv, index, W, H) {
  const cov = new Uint8Array(W * H);
  for (let t = 0; t < index.length; t += 3) {
    const ia = index[t] * 2, ib = index[t + 1] * 2, ic = index[t + 2] * 2;
    let ax = uv[ia] * W, ay = uv[ia + 1] * H;
    let bx = uv[ib] * W, by = uv[ib + 1] * H;
    let cx = uv[ic] * W, cy = uv[ic + 1] * H;
    let area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    if (!(area !== 0)) continue; // degenerate or NaN
    if (area < 0) { let s = bx; bx = cx; cx = s; s = by; by = cy; cy = s; area = -area; }
    const x0 = Math.max(0, Math.ceil(Math.min(ax, bx, cx) - 0.5));
    const x1 = Math.min(W - 1, Math.floor(Math.max(ax, bx, cx) - 0.5));
    const y0 = Math.max(0, Math.ceil(Math.min(ay, by, cy) - 0.5));
    const y1 = Math.min(H - 1, Math.floor(Math.max(ay, by, cy) - 0.5));
    const eps = -1e-7 * area;
    for (let y = y0; y <= y1; y++) {
      const py = y + 0.5;
      const row = y * W;
      for (let x = x0; x <= x1; x++) {
        const px = x + 0.5;
        const w0 = (bx - ax) * (py - ay) - (by - ay) * (px - ax);
        const w1 = (cx - bx) * (py - by) - (cy - by) * (px - bx);
        const w2 = (ax - cx) * (py - cy) - (ay - cy) * (px - cx);
        if (w0 >= eps && w1 >= eps && w2 >= eps) cov[row + x] = 1;
      }
    }
  }
  let n = 0;
  for (let i = 0; i < cov.length; i++) n += cov[i];
  return n / (W * H);
}

// ---------------------------------------------------------------- main

async function main() {
  const opts = parseArgs(process.argv.slice(2));
  const mesh = readObj(opts.file);
  const nVerts = mesh.positions.length / 3;
  const nFaces = mesh.indices.length / 3;
  // The xatlasjs binding takes 16-bit input indices.
  if (nVerts > 65535)
    fail(`'${opts.file}': ${nVerts} vertices; the ${PKG_NAME} binding takes 16-bit indices (at most 65535 vertices)`);

  let pkgVersion = 'unknown';
  let createModule;
  try {
    pkgVersion = JSON.parse(fs.readFileSync(require.resolve(`${PKG_NAME}/package.json`), 'utf8')).version;
    createModule = require(`${PKG_NAME}/dist/node/xatlas.js`);
  } catch (e) {
    fail(`cannot load ${PKG_NAME} (${e.code || e.message}); run: npm ci --prefix ${path.relative(process.cwd(), here) || '.'}`);
  }

  // Progress events (category, percent) timestamp the phase boundaries
  // inside the single generateAtlas call: 1 = compute charts (includes
  // parameterisation), 2 = pack charts, 3 = build output meshes.
  let lastChartEvent = -1, firstPackEvent = -1;
  const onAtlasProgress = (category, _progress) => {
    const now = performance.now();
    if (category === 1) lastChartEvent = now;
    else if (category >= 2 && firstPackEvent < 0) firstPackEvent = now;
  };
  const toErr = (s) => process.stderr.write(String(s) + '\n');

  const tInit0 = performance.now();
  const X = await createModule({ onAtlasProgress, print: toErr, printErr: toErr });
  const secondsInit = (performance.now() - tInit0) / 1000;

  X.createAtlas();
  const desc = X.createMesh(nVerts, mesh.indices.length, false, false);
  X.HEAPU16.set(mesh.indices, desc.indexOffset / 2);
  X.HEAPF32.set(mesh.positions, desc.positionOffset / 4);
  const addErr = X.addMesh();
  if (addErr !== 0) fail(`'${opts.file}': xatlas AddMesh failed with error code ${addErr}`);

  const chartOptions = { ...X.defaultChartOptions() };
  const packOptions = { ...X.defaultPackOptions(), resolution: opts.resolution, padding: opts.padding };

  lastChartEvent = firstPackEvent = -1;
  const t0 = performance.now();
  X.generateAtlas(chartOptions, packOptions);
  const t1 = performance.now();

  const atlas = X.getAtlas();
  const md = X.getMeshData(desc.meshId);
  const W = atlas.width, H = atlas.height;
  const outVerts = md.newVertexCount;
  const index = new Uint32Array(X.HEAPU32.subarray(md.indexOffset / 4, md.indexOffset / 4 + md.newIndexCount));
  const uv = new Float32Array(X.HEAPF32.subarray(md.uvOffset / 4, md.uvOffset / 4 + outVerts * 2));
  X.destroyMeshData(md);
  md.subMeshes.delete();
  X.destroyAtlas();

  if (!(W > 0 && H > 0)) fail(`'${opts.file}': xatlas produced an empty atlas (${W}x${H})`);

  const charts = countCharts(index, outVerts);
  const utilisation = rasterUtilisation(uv, index, W, H);

  const split = lastChartEvent >= 0 ? lastChartEvent : (firstPackEvent >= 0 ? firstPackEvent : t1);
  const r6 = (x) => Math.round(x * 1e6) / 1e6;
  const out = {
    tool: 'xatlas',
    package: `${PKG_NAME}@${pkgVersion}`,
    faces: nFaces,
    charts,
    atlas_width: W,
    atlas_height: H,
    utilisation: r6(utilisation),
    utilisation_source: 'rasterised',
    seconds: r6((t1 - t0) / 1000),
    seconds_charts: r6((split - t0) / 1000),
    seconds_pack: r6((t1 - split) / 1000),
    seconds_init: r6(secondsInit),
    resolution: opts.resolution,
    padding: opts.padding,
    atlas_count: atlas.atlasCount,
    texels_per_unit: r6(atlas.texelsPerUnit),
    vertices_in: nVerts,
    vertices_out: outVerts,
  };
  process.stdout.write(JSON.stringify(out) + '\n');
}

main().catch((e) => fail(e && e.stack ? e.stack : String(e)));
