// Shared by the web tests: running the radiosity binary, a minimal PNG
// decoder (8-bit RGB/RGBA, non-interlaced: what our renderer and Chromium
// write) and Chromium's launch flags for this machine.
import { spawnSync } from 'node:child_process';
import { mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { inflateSync } from 'node:zlib';

export const BIN = process.env.RADIOSITY_BIN;
if (!BIN) throw new Error('RADIOSITY_BIN is not set (run through .ci/web-tests)');

/** Longest any one wait of the web tests may take, ms: a safety net far
 * above what any of them needs, even on one busy core. No test waits for
 * time to pass: each waits for an event (a line printed, a frame drawn, a
 * value shown) and fails only if it never comes. */
export const PATIENCE = 300_000;

/** A fresh temporary folder. */
export function tempDir(prefix) {
  return mkdtempSync(join(tmpdir(), `radiosity-${prefix}-`));
}

/** Runs the binary on the CPU (the tests compare with CPU results);
 * throws with its stderr on failure. */
export function radiosity(args, options = {}) {
  const env = { ...process.env, RADIOSITY_DEVICE: 'cpu', ...(options.env ?? {}) };
  const r = spawnSync(BIN, args, { encoding: 'utf8', ...options, env });
  if (r.status !== 0) {
    throw new Error(`radiosity ${args.join(' ')} failed (${r.status}): ${r.stderr}`);
  }
  return r.stdout;
}

/** Chromium flags: headless, no sandbox (root), software WebGL
 * (SwiftShader through ANGLE), and no background network traffic, which
 * this machine's closed network refuses. */
export const CHROMIUM_ARGS = [
  '--headless', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--ignore-gpu-blocklist', '--disable-quic', '--no-first-run', '--disable-background-networking',
  '--disable-component-update', '--disable-sync', '--force-color-profile=srgb',
];

/** Decodes a PNG into { width, height, rgb } (rgb: 3 bytes a pixel). */
export function decodePng(buffer) {
  const signature = '89504e470d0a1a0a';
  if (buffer.subarray(0, 8).toString('hex') !== signature) throw new Error('not a PNG');
  let at = 8;
  let width = 0; let height = 0; let channels = 0;
  const idat = [];
  while (at < buffer.length) {
    const length = buffer.readUInt32BE(at);
    const type = buffer.toString('latin1', at + 4, at + 8);
    const data = buffer.subarray(at + 8, at + 8 + length);
    if (type === 'IHDR') {
      width = data.readUInt32BE(0);
      height = data.readUInt32BE(4);
      const depth = data[8]; const colour = data[9]; const interlace = data[12];
      if (depth !== 8 || interlace !== 0 || (colour !== 2 && colour !== 6)) {
        throw new Error(`unsupported PNG (depth ${depth}, colour type ${colour}, interlace ${interlace})`);
      }
      channels = colour === 2 ? 3 : 4;
    } else if (type === 'IDAT') {
      idat.push(data);
    } else if (type === 'IEND') {
      break;
    }
    at += 12 + length;
  }
  const raw = inflateSync(Buffer.concat(idat));
  const stride = width * channels;
  const pixels = Buffer.alloc(stride * height);
  for (let y = 0; y < height; y++) {
    const filter = raw[y * (stride + 1)];
    const line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let x = 0; x < stride; x++) {
      const a = x >= channels ? pixels[y * stride + x - channels] : 0;
      const b = y > 0 ? pixels[(y - 1) * stride + x] : 0;
      const c = x >= channels && y > 0 ? pixels[(y - 1) * stride + x - channels] : 0;
      let v = line[x];
      if (filter === 1) v += a;
      else if (filter === 2) v += b;
      else if (filter === 3) v += (a + b) >> 1;
      else if (filter === 4) {
        const p = a + b - c;
        const pa = Math.abs(p - a); const pb = Math.abs(p - b); const pc = Math.abs(p - c);
        v += pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      pixels[y * stride + x] = v & 255;
    }
  }
  const rgb = Buffer.alloc(width * height * 3);
  for (let i = 0; i < width * height; i++) {
    for (let k = 0; k < 3; k++) rgb[3 * i + k] = pixels[channels * i + k];
  }
  return { width, height, rgb };
}
