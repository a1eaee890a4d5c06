// The node half of bench/laz_interop.sh: decodes LAZ files with LAZperf (the npm package
// laz-perf, a WebAssembly build of Hobu's LAZperf) and compares every record byte for byte
// with an uncompressed LAS file; also derives LAS inputs in point formats that tessera-lod
// export does not make from scans (0, 1, 2, 8, extra bytes) from ones it does.
//
//   node laz_interop.mjs derive SRC.las DST.las FORMAT [EXTRA_BYTES]
//   node laz_interop.mjs compare --lazperf DIR --csv OUT.csv --pair NAME WRITER LAZ LAS [--pair ...]
//
// compare appends a row per pair to OUT.csv (file,point_format,points,laz_perf_equal,writer,
// reference,first_difference), prints a line per pair and exits 1 when any pair differs.
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';

const BASE_LENGTH = { 0: 20, 1: 28, 2: 26, 3: 34, 6: 30, 7: 36, 8: 38 };

// Byte ranges of the fields of each point format, to name the field of a differing byte.
function fieldAt(format, offset) {
  const common = [['X', 0, 4], ['Y', 4, 4], ['Z', 8, 4], ['intensity', 12, 2]];
  const legacy = [...common, ['return bits', 14, 1], ['classification', 15, 1],
    ['scan angle rank', 16, 1], ['user data', 17, 1], ['point source id', 18, 2]];
  const layered = [...common, ['return numbers', 14, 1], ['class flags/channel', 15, 1],
    ['classification', 16, 1], ['user data', 17, 1], ['scan angle', 18, 2],
    ['point source id', 20, 2], ['GPS time', 22, 8]];
  const rgb = (at) => [['red', at, 2], ['green', at + 2, 2], ['blue', at + 4, 2]];
  const fields = {
    0: legacy,
    1: [...legacy, ['GPS time', 20, 8]],
    2: [...legacy, ...rgb(20)],
    3: [...legacy, ['GPS time', 20, 8], ...rgb(28)],
    6: layered,
    7: [...layered, ...rgb(30)],
    8: [...layered, ...rgb(30), ['NIR', 36, 2]],
  }[format] || [];
  for (const [name, start, size] of fields) {
    if (offset >= start && offset < start + size) return name;
  }
  return offset >= (BASE_LENGTH[format] ?? 0) ? 'extra bytes' : 'unknown';
}

// The header fields of a LAS or LAZ file that locate its records.
function lasHeader(bytes, file) {
  if (bytes.length < 227 || bytes.toString('latin1', 0, 4) !== 'LASF') {
    throw new Error(`${file}: not a LAS file (no LASF signature)`);
  }
  const minor = bytes[25];
  const formatByte = bytes[104];
  const h = {
    minor,
    headerSize: bytes.readUInt16LE(94),
    offset: bytes.readUInt32LE(96),
    vlrCount: bytes.readUInt32LE(100),
    formatByte,
    format: formatByte & 0x3f,
    compressed: (formatByte & 0x80) !== 0,
    recordLength: bytes.readUInt16LE(105),
    count: bytes.readUInt32LE(107),
    evlrStart: 0n,
    evlrCount: 0,
  };
  if (minor >= 4) {
    if (bytes.length < 375) throw new Error(`${file}: LAS 1.${minor} header is shorter than 375 bytes`);
    h.evlrStart = bytes.readBigUInt64LE(235);
    h.evlrCount = bytes.readUInt32LE(243);
    h.count = Number(bytes.readBigUInt64LE(247));
  }
  return h;
}

function vlrs(bytes, h) {
  const out = [];
  let at = h.headerSize;
  for (let i = 0; i < h.vlrCount; i++) {
    const length = bytes.readUInt16LE(at + 20);
    out.push({
      user: bytes.toString('latin1', at + 2, at + 18).replace(/\0.*$/s, ''),
      record: bytes.readUInt16LE(at + 18),
      bytes: bytes.subarray(at, at + 54 + length),
    });
    at += 54 + length;
  }
  if (at > h.offset) throw new Error('VLRs run past the point data');
  return out;
}

// ---- derive: a LAS file in another point format from one tessera-lod wrote ----------------

// An Extra Bytes VLR (LASF_Spec 4) describing `count` undocumented bytes.
function extraBytesVlr(count) {
  const v = Buffer.alloc(54 + 192);
  v.write('LASF_Spec', 2, 'latin1');
  v.writeUInt16LE(4, 18);
  v.writeUInt16LE(192, 20);
  v.write('interop extra bytes', 22, 'latin1');
  const d = 54;
  v[d + 2] = 0; // data type 0: undocumented bytes, options = how many
  v[d + 3] = count;
  v.write('tessera_interop', d + 4, 'latin1');
  v.write('bytes made by bench/laz_interop', d + 160, 'latin1');
  return v;
}

// Bytes that change slowly along the records, as real attributes do, and a last one that jumps.
function writeExtraBytes(o, at, extra, i, r) {
  for (let e = 0; e < extra; e++) {
    o[at + e] = e === extra - 1 ? (i * 37 + 11) & 0xff : ((i >> (2 * e)) + r[e]) & 0xff;
  }
}

// A LAS 1.2 record (formats 0-3) as a LAS 1.4 one (formats 6-8): the same position, intensity,
// returns, flags, classification, scan angle, user data, source, GPS time and colour, the
// scanner channel switching among four every 64 points and a near-infrared channel made up.
function upgradeRecord(r, srcFormat, o, format, i) {
  r.copy(o, 0, 0, 14); // X, Y, Z, intensity
  const bits = r[14];
  o[14] = (bits & 0x07) | (((bits >> 3) & 0x07) << 4); // return number, number of returns
  const channel = ((i >> 6) + r.readUInt16LE(18)) & 3;
  o[15] = ((r[15] >> 5) & 0x07) | (channel << 4) | (bits & 0xc0); // class flags, channel, dir, edge
  o[16] = r[15] & 0x1f; // classification
  o[17] = r[17]; // user data
  o.writeInt16LE(Math.round(r.readInt8(16) / 0.006), 18); // scan angle in 0.006 degrees
  r.copy(o, 20, 18, 20); // point source id
  if (srcFormat === 1 || srcFormat === 3) r.copy(o, 22, 20, 28); // GPS time
  else o.writeDoubleLE(1000 + i * 0.25, 22);
  if (format >= 7) {
    const rgb = srcFormat === 2 ? 20 : srcFormat === 3 ? 28 : -1;
    if (rgb >= 0) r.copy(o, 30, rgb, rgb + 6);
    else for (let c = 0; c < 3; c++) o.writeUInt16LE((i * (c + 3)) & 0xffff, 30 + 2 * c);
  }
  if (format === 8) {
    const red = o.readUInt16LE(30);
    o.writeUInt16LE((red ^ ((i * 2654435761) >>> 22)) & 0xffff, 36);
  }
}

// A LAS 1.2 record in another LAS 1.2 format, or a LAS 1.4 one in another LAS 1.4 format.
function convertRecord(r, srcFormat, o, format, i) {
  if (format < 6) {
    r.copy(o, 0, 0, 20); // the format 0 core
    const gps = srcFormat === 1 || srcFormat === 3 ? 20 : -1;
    const rgb = srcFormat === 2 ? 20 : srcFormat === 3 ? 28 : -1;
    if (format === 1 || format === 3) {
      if (gps >= 0) r.copy(o, 20, gps, gps + 8); else o.writeDoubleLE(1000 + i * 0.25, 20);
    }
    if (format === 2 || format === 3) {
      const at = format === 2 ? 20 : 28;
      if (rgb >= 0) r.copy(o, at, rgb, rgb + 6);
      else for (let c = 0; c < 3; c++) o.writeUInt16LE((i * (c + 3)) & 0xffff, at + 2 * c);
    }
    return;
  }
  r.copy(o, 0, 0, 30); // the format 6 core
  if (format >= 7) {
    if (srcFormat >= 7) r.copy(o, 30, 30, 36);
    else for (let c = 0; c < 3; c++) o.writeUInt16LE((i * (c + 3)) & 0xffff, 30 + 2 * c);
  }
  if (format === 8) {
    if (srcFormat === 8) r.copy(o, 36, 36, 38);
    else o.writeUInt16LE((o.readUInt16LE(30) ^ ((i * 2654435761) >>> 22)) & 0xffff, 36);
  }
}

function derive(src, dst, format, extra) {
  const bytes = fs.readFileSync(src);
  const h = lasHeader(bytes, src);
  if (h.compressed) throw new Error(`${src}: derive needs an uncompressed LAS file`);
  if (!(format in BASE_LENGTH)) throw new Error(`format ${format} is not one of 0-3, 6-8`);
  if (!(h.format in BASE_LENGTH)) throw new Error(`${src}: format ${h.format} is not one of 0-3, 6-8`);
  if (format < 6 && h.format >= 6) {
    throw new Error(`${src}: format ${h.format} (LAS 1.4 layout) cannot become format ${format}`);
  }
  if (!Number.isInteger(extra) || extra < 0 || extra > 200) throw new Error(`bad extra byte count ${extra}`);
  const upgrade = format >= 6 && h.format < 6;
  const length = BASE_LENGTH[format] + extra;
  // The LAZ VLR and any Extra Bytes VLR no longer describe the records; a LAS 1.2 file's
  // GeoTIFF keys are not the WKT that LAS 1.4 formats 6-10 ask for, so an upgrade drops them.
  const keep = vlrs(bytes, h).filter((v) => v.user !== 'laszip encoded' &&
    !(v.user === 'LASF_Spec' && v.record === 4) &&
    !(upgrade && (v.user === 'LASF_Projection' || v.user === 'liblas')));
  if (extra > 0) keep.push({ bytes: extraBytesVlr(extra) });
  const vlrBytes = Buffer.concat(keep.map((v) => v.bytes));
  const headerSize = upgrade ? 375 : h.headerSize;
  const offset = headerSize + vlrBytes.length;
  const records = Buffer.alloc(h.count * length);
  const byReturn = new Array(15).fill(0n);
  for (let i = 0; i < h.count; i++) {
    const r = bytes.subarray(h.offset + i * h.recordLength, h.offset + (i + 1) * h.recordLength);
    const o = records.subarray(i * length, (i + 1) * length);
    if (upgrade) {
      upgradeRecord(r, h.format, o, format, i);
      const n = o[14] & 0x0f;
      if (n >= 1) byReturn[n - 1]++;
    } else {
      convertRecord(r, h.format, o, format, i);
    }
    writeExtraBytes(o, BASE_LENGTH[format], extra, i, r);
  }
  const header = Buffer.alloc(headerSize);
  bytes.copy(header, 0, 0, Math.min(h.headerSize, headerSize));
  header.writeUInt32LE(offset, 96);
  header.writeUInt32LE(keep.length, 100);
  header[104] = format;
  header.writeUInt16LE(length, 105);
  let tail = bytes.subarray(h.offset + h.count * h.recordLength);
  if (upgrade) {
    header[25] = 4; // LAS 1.4
    header.writeUInt16LE(headerSize, 94);
    header.writeUInt16LE((header.readUInt16LE(6) & 0x01) | 0x10, 6); // GPS time type, WKT
    header.writeUInt32LE(0, 107); // formats 6-10 leave the legacy counts 0
    header.fill(0, 111, 131);
    header.fill(0, 227, 375); // no waveforms, no EVLRs
    header.writeBigUInt64LE(BigInt(h.count), 247);
    byReturn.forEach((n, k) => header.writeBigUInt64LE(n, 255 + 8 * k));
    tail = Buffer.alloc(0);
  } else if (h.minor >= 4 && h.evlrCount > 0) {
    header.writeBigUInt64LE(BigInt(offset + records.length), 235);
  }
  fs.writeFileSync(dst, Buffer.concat([header, vlrBytes, records, tail]));
}

// ---- compare: LAZperf's records against a LAS file's ----------------------------------------

async function loadLazPerf(dir) {
  const require = createRequire(path.join(path.resolve(dir), 'node_modules', 'noop.js'));
  let mod;
  try {
    mod = require('laz-perf');
  } catch (e) {
    throw new Error(`cannot load laz-perf from ${dir}/node_modules: ${e.message}`);
  }
  const create = mod.createLazPerf || mod.create || mod.default;
  return { module: await create(), version: require('laz-perf/package.json').version };
}

function describeError(L, e) {
  if (typeof e === 'number' && L.getExceptionMessage) {
    try { return L.getExceptionMessage(e).join(': '); } catch { /* fall through */ }
  }
  if (e && /Exception catching is disabled/.test(e.message ?? String(e))) {
    return 'it threw a C++ exception (this laz-perf build does not carry the message)';
  }
  return e && e.message ? e.message : `it threw ${String(e)}`;
}

function hex(bytes) {
  return Array.from(bytes, (b) => b.toString(16).padStart(2, '0')).join(' ');
}

function comparePair(L, lazFile, lasFile) {
  const laz = fs.readFileSync(lazFile);
  const las = fs.readFileSync(lasFile);
  const hz = lasHeader(laz, lazFile);
  const hs = lasHeader(las, lasFile);
  const result = { format: hz.format, points: hz.count, equal: false, detail: '' };
  if (!hz.compressed) {
    result.detail = `${path.basename(lazFile)} is not LAZ (point format byte 0x${hz.formatByte.toString(16)})`;
    return result;
  }
  if (hs.compressed) {
    result.detail = `${path.basename(lasFile)} is compressed; the reference must be plain LAS`;
    return result;
  }
  const ptr = L._malloc(laz.length);
  let zip = null;
  let point = 0;
  try {
    L.HEAPU8.set(laz, ptr);
    zip = new L.LASZip();
    zip.open(ptr, laz.length);
    const count = zip.getCount();
    const length = zip.getPointLength();
    const format = zip.getPointFormat();
    result.format = format;
    result.points = count;
    const mismatch = [];
    if (format !== hs.format) mismatch.push(`point format ${format} vs ${hs.format}`);
    if (length !== hs.recordLength) mismatch.push(`record length ${length} vs ${hs.recordLength}`);
    if (count !== hs.count) mismatch.push(`points ${count} vs ${hs.count}`);
    if (mismatch.length) {
      result.detail = `LAZperf vs reference header: ${mismatch.join(', ')}`;
      return result;
    }
    if (las.length < hs.offset + count * length) {
      result.detail = `${path.basename(lasFile)} holds fewer than ${count} records`;
      return result;
    }
    point = L._malloc(length);
    for (let i = 0; i < count; i++) {
      try {
        zip.getPoint(point);
      } catch (e) {
        result.detail = `LAZperf failed at record ${i}: ${describeError(L, e)}`;
        result.threw = true;
        return result;
      }
      const got = L.HEAPU8.subarray(point, point + length); // HEAPU8 is renewed when memory grows
      const want = las.subarray(hs.offset + i * length, hs.offset + (i + 1) * length);
      if (Buffer.compare(got, want) !== 0) {
        let b = 0;
        while (got[b] === want[b]) b++;
        result.detail = `record ${i} byte ${b} (${fieldAt(format, b)}): LAZperf [${hex(got)}] ` +
          `reference [${hex(want)}]`;
        return result;
      }
    }
    result.equal = true;
    return result;
  } catch (e) {
    result.detail = `LAZperf cannot open ${path.basename(lazFile)}: ${describeError(L, e)}`;
    result.threw = true;
    return result;
  } finally {
    if (point) L._free(point);
    if (zip) zip.delete();
    L._free(ptr);
  }
}

async function compare(args) {
  let dir = null;
  let csv = null;
  const pairs = [];
  for (let i = 0; i < args.length; i++) {
    if (args[i] === '--lazperf') dir = args[++i];
    else if (args[i] === '--csv') csv = args[++i];
    else if (args[i] === '--pair' && i + 4 < args.length) {
      pairs.push(args.slice(i + 1, i + 5));
      i += 4;
    } else usage();
  }
  if (!dir || !csv || pairs.length === 0) usage();
  let { module: L, version } = await loadLazPerf(dir);
  console.log(`LAZperf: laz-perf ${version} (WebAssembly) from ${dir}`);
  let failed = 0;
  for (const [name, writer, lazFile, lasFile] of pairs) {
    const t0 = performance.now();
    const r = comparePair(L, lazFile, lasFile);
    const ms = performance.now() - t0;
    if (!r.equal) failed++;
    if (r.threw) L = (await loadLazPerf(dir)).module; // a fresh instance after an exception
    const reference = path.basename(lasFile);
    console.log(`${r.equal ? 'equal  ' : 'DIFFER '} ${name.padEnd(26)} format ${r.format}  ` +
      `${String(r.points).padStart(7)} points  written by ${writer}, against ${reference}` +
      `${r.equal ? '' : `\n        ${r.detail}`}  (${ms.toFixed(0)} ms)`);
    const quote = (s) => (/[",\n]/.test(s) ? `"${s.replace(/"/g, '""')}"` : s);
    fs.appendFileSync(csv, [name, r.format, r.points, r.equal ? 'yes' : 'no', writer, reference,
      r.detail].map((v) => quote(String(v))).join(',') + '\n');
  }
  process.exitCode = failed ? 1 : 0;
}

function usage() {
  console.error('usage: node laz_interop.mjs derive SRC.las DST.las FORMAT [EXTRA_BYTES]\n' +
    '       node laz_interop.mjs compare --lazperf DIR --csv OUT.csv --pair NAME WRITER LAZ LAS [--pair ...]');
  process.exit(2);
}

const [command, ...rest] = process.argv.slice(2);
try {
  if (command === 'derive' && (rest.length === 3 || rest.length === 4)) {
    derive(rest[0], rest[1], Number(rest[2]), Number(rest[3] ?? 0));
  } else if (command === 'compare') {
    await compare(rest);
  } else {
    usage();
  }
} catch (e) {
  console.error(`laz_interop.mjs: ${e.message}`);
  process.exit(2);
}
