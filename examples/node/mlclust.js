'use strict';
// A Node client for the mlclust service, written from proto/mlclust/v1/mlclust.proto alone
// (loaded at run time with @grpc/proto-loader) and draco3d for the upload.
//
// An npm package too: `npm install ./examples/node` (a link to this folder), or `npm pack`
// here and `npm install mlclust-VERSION.tgz` (the proto and the dependencies bundled; no
// registry needed); then require('mlclust'). mlclust.version is the server's VERSION.
//
//   const mlclust = require('./mlclust');
//   const client = new mlclust.Client('localhost:50051');
//   const h = await client.clusterMesh({vertices, faces}, {algo: 'ml', energy: 'cvd'});
//   h.labels(100);  // one cluster id 0..99 per face, in the order of `faces`
const fs = require('fs');
const path = require('path');
const grpc = require('@grpc/grpc-js');
const protoLoader = require('@grpc/proto-loader');
const draco3d = require('draco3d');

// The proto: the copy an installed package carries (package.json's prepack bundles it), else
// the repository's, two folders up (examples/node used in place or installed as a link).
const PROTO_FILE = [
  path.join(__dirname, 'proto', 'mlclust', 'v1', 'mlclust.proto'),
  path.join(__dirname, '..', '..', 'proto', 'mlclust', 'v1', 'mlclust.proto'),
].find((file) => fs.existsSync(file));
const FACE_ID_NAME = 'mlclust_face_id';  // the per-face id attribute's metadata "name"
const LITTLE_ENDIAN = new Uint8Array(new Uint32Array([1]).buffer)[0] === 1;

/** A failed call or job: `code` is the gRPC status (a number), `codeName` its name. */
class MlclustError extends Error {
  constructor(code, details) {
    const codeName = Object.keys(grpc.status).find((k) => grpc.status[k] === code) || 'UNKNOWN';
    super(`${codeName}: ${details}`);
    Object.assign(this, {code, codeName, details});
  }
}

// CRC-32 (IEEE 802.3, zlib's) for JobSpec.input_crc32; Node 18's zlib has none.
const CRC_TABLE = Uint32Array.from({length: 256}, (_, n) => {
  let c = n;
  for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});
function crc32(bytes) {
  let c = 0xffffffff;
  for (let i = 0; i < bytes.length; i++) c = CRC_TABLE[(c ^ bytes[i]) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

let encoderModule = null;  // draco3d's encoder (WebAssembly), created once
/**
 * The mesh as Draco bytes. method 'sequential' keeps the face order; 'edgebreaker' (several
 * times smaller with quantizationBits, e.g. 14) reorders faces, so by default it carries the
 * per-face id attribute of our contract: a point per face corner holding its position and
 * its face's index, a GENERIC uint32 attribute with metadata name "mlclust_face_id". The
 * encoder's deduplication welds corners at equal positions back into vertices.
 */
async function encodeMesh(
    {vertices, faces},
    {method = 'sequential',
     quantizationBits = 0,
     faceIds = method === 'edgebreaker',
     speed = 5} = {}) {
  encoderModule = encoderModule || await draco3d.createEncoderModule({});
  const M = encoderModule;
  const positions = Float32Array.from(vertices.flat ? vertices.flat() : vertices);
  const corners = Uint32Array.from(faces.flat ? faces.flat() : faces);
  const numFaces = corners.length / 3;
  const mesh = new M.Mesh();
  const builder = new M.MeshBuilder();
  const encoder = new M.Encoder();
  const out = new M.DracoInt8Array();
  try {
    if (!faceIds) {
      builder.AddFacesToMesh(mesh, numFaces, corners);
      builder.AddFloatAttribute(mesh, M.POSITION, positions.length / 3, 3, positions);
    } else {
      const cornerPositions = new Float32Array(9 * numFaces);
      const ids = new Uint32Array(3 * numFaces);
      const points = new Uint32Array(3 * numFaces);  // point 3f + c: corner c of face f
      for (let p = 0; p < 3 * numFaces; p++) {
        for (let d = 0; d < 3; d++) cornerPositions[3 * p + d] = positions[3 * corners[p] + d];
        ids[p] = (p - (p % 3)) / 3;
        points[p] = p;
      }
      builder.AddFacesToMesh(mesh, numFaces, points);
      builder.AddFloatAttribute(mesh, M.POSITION, 3 * numFaces, 3, cornerPositions);
      const idAttribute = builder.AddUInt32Attribute(mesh, M.GENERIC, 3 * numFaces, 1, ids);
      const metadata = new M.Metadata();
      new M.MetadataBuilder().AddStringEntry(metadata, 'name', FACE_ID_NAME);
      builder.SetMetadataForAttribute(mesh, idAttribute, metadata);
    }
    encoder.SetEncodingMethod(
        method === 'edgebreaker' ? M.MESH_EDGEBREAKER_ENCODING : M.MESH_SEQUENTIAL_ENCODING);
    encoder.SetSpeedOptions(speed, speed);
    if (quantizationBits > 0) encoder.SetAttributeQuantization(M.POSITION, quantizationBits);
    const length = encoder.EncodeMeshToDracoBuffer(mesh, out);
    if (length <= 0)
      throw new MlclustError(grpc.status.INVALID_ARGUMENT, 'draco3d could not encode the mesh');
    const bytes = Buffer.alloc(length);
    for (let i = 0; i < length; i++) bytes[i] = out.GetValue(i) & 0xff;
    return bytes;
  } finally {
    [out, encoder, builder, mesh].forEach((o) => M.destroy(o));
  }
}

/** uint32 values of a repeated field (an array) or of a packed little-endian bytes field. */
function uint32s(repeated, packed) {
  if (!packed || packed.length === 0) return Uint32Array.from(repeated);
  if (repeated.length)
    throw new MlclustError(grpc.status.DATA_LOSS, 'both packed and repeated triplets');
  if (packed.length % 4)
    throw new MlclustError(grpc.status.DATA_LOSS, 'packed triplets not a multiple of 4 bytes');
  if (LITTLE_ENDIAN) {  // viewed in place where 4-byte aligned, copied otherwise
    const bytes = packed.byteOffset % 4 ? new Uint8Array(packed) : packed;
    return new Uint32Array(bytes.buffer, bytes.byteOffset, bytes.length / 4);
  }
  return Uint32Array.from({length: packed.length / 4}, (_, i) => packed.readUInt32LE(4 * i));
}

/** A growable Uint32Array. */
class Column {
  constructor() {
    this.data = new Uint32Array(1024);
    this.size = 0;
  }
  push(values) {
    if (this.size + values.length > this.data.length) {
      const grown = new Uint32Array(Math.max(2 * this.data.length, this.size + values.length));
      grown.set(this.data.subarray(0, this.size));
      this.data = grown;
    }
    this.data.set(values, this.size);
    this.size += values.length;
  }
  view() {
    return this.data.subarray(0, this.size);
  }
}

/**
 * Every level a job sent. Level 0 is the snapshot; level i > 0 lists the elements that
 * changed cluster from level i - 1 as triplets (element, to, from): stepping forward applies
 * `to`, stepping back applies `from`. `levels[i]` = {clusterCount, energy, sourceLevel}.
 */
class Hierarchy {
  constructor(snapshot, levels, ends, element, to, from) {
    Object.assign(this, {levels, ends, element, to, from});
    this.current = Uint32Array.from(snapshot);  // the server's cluster ids at `position`
    this.position = 0;
  }
  /** The last level with exactly k clusters, else the first with fewer (as the CLI). */
  levelFor(k) {
    const counts = this.levels.map((l) => l.clusterCount);
    const exact = counts.lastIndexOf(k);
    const fewer = counts.findIndex((c) => c <= k);
    if (exact < 0 && fewer < 0) throw new RangeError(`no level has ${k} clusters or fewer`);
    return exact >= 0 ? exact : fewer;
  }
  /** Moves the cursor to `level` by applying the triplets in between. */
  seek(level) {
    if (!(level >= 0 && level < this.levels.length)) throw new RangeError(`no level ${level}`);
    for (; this.position < level; this.position++) {  // forwards: level position + 1
      for (let t = this.ends[this.position]; t < this.ends[this.position + 1]; t++) {
        this.current[this.element[t]] = this.to[t];
      }
    }
    for (; this.position > level; this.position--) {  // backwards: undo level position
      for (let t = this.ends[this.position] - 1; t >= this.ends[this.position - 1]; t--) {
        this.current[this.element[t]] = this.from[t];
      }
    }
    return this;
  }
  /**
   * Labels at the level with k clusters (or {level}): 0..K-1 in order of first appearance
   * (as the CLI's --labels), or the server's own ids with {compact: false}.
   */
  labels(k, {level = undefined, compact = true} = {}) {
    this.seek(level === undefined ? this.levelFor(k) : level);
    if (!compact) return Uint32Array.from(this.current);
    const rank = new Map();
    return this.current.map((id) => {
      if (!rank.has(id)) rank.set(id, rank.size);
      return rank.get(id);
    });
  }
}

/** Collects one job's events into a Hierarchy, checking that the stream is consistent. */
class Assembler {
  /** absolute: batches number levels as the job does (Watch), from the snapshot's level. */
  constructor(absolute = false) {
    this.absolute = absolute;
    this.offset = 0;
    this.snapshot = null;
    this.have = 0;
    this.levels = [];
    this.ends = [0];
    this.element = new Column();
    this.to = new Column();
    this.from = new Column();
    this.continuing = false;
    this.messages = {snapshot: 0, levels: 0, continued: 0};  // how the levels travelled
  }
  add(event) {
    const fail = (what) => {
      throw new MlclustError(grpc.status.DATA_LOSS, what);
    };
    if (event.event === 'snapshot') {
      const s = event.snapshot;
      this.messages.snapshot++;
      if (s.first_element !== this.have)
        fail(`snapshot piece at ${s.first_element}, expected ${this.have}`);
      if (!this.snapshot) this.snapshot = new Uint32Array(s.total_elements);
      if (this.have + s.labels.length > this.snapshot.length)
        fail('more labels than total_elements');
      this.snapshot.set(s.labels, this.have);
      this.have += s.labels.length;
      if (this.have === s.total_elements) {
        if (this.absolute) this.offset = s.level;
        this.levels.push({clusterCount: s.cluster_count, energy: s.energy, sourceLevel: s.level});
      }
    } else if (event.event === 'levels') {
      const b = event.levels;
      this.messages.levels++;
      if (b.last_level_continues) this.messages.continued++;
      if (!this.levels.length) fail('levels before the snapshot');
      const expected = this.levels.length - (this.continuing ? 1 : 0);
      if (b.first_level - this.offset !== expected) {
        fail(`levels from ${b.first_level}, expected ${expected + this.offset}`);
      }
      const element = uint32s(b.element, b.packed_element);
      const base = this.element.size;
      this.element.push(element);
      this.to.push(uint32s(b.to_cluster, b.packed_to_cluster));
      this.from.push(uint32s(b.from_cluster, b.packed_from_cluster));
      if (this.to.size !== this.element.size || this.from.size !== this.element.size)
        fail('triplet arrays differ in length');
      if (element.some((e) => e >= this.have)) fail('a triplet names an element out of range');
      const n = b.cluster_count.length;
      if (b.energy.length !== n || b.triplet_end.length !== n)
        fail('level arrays differ in length');
      if (b.triplet_end.some((end, i) => end < (i ? b.triplet_end[i - 1] : 0)) ||
          (n && b.triplet_end[n - 1] > element.length)) {
        fail('triplet_end out of order');
      }
      if (this.continuing && n && b.cluster_count[0] !== this.levels[expected].clusterCount) {
        fail(`level ${expected} continued with another cluster count`);
      }
      b.cluster_count.forEach((count, i) => {
        const end = base + b.triplet_end[i];
        if (i === 0 && this.continuing) {  // the rest of the previous batch's last level
          this.ends[this.ends.length - 1] = end;
        } else {
          this.levels.push(
              {clusterCount: count, energy: b.energy[i], sourceLevel: b.source_level[i]});
          this.ends.push(end);
        }
      });
      if (b.cluster_count.length) this.continuing = b.last_level_continues;
    }
  }
  finish() {
    if (!this.levels.length || this.continuing)
      throw new MlclustError(grpc.status.DATA_LOSS, 'the job ended with its levels incomplete');
    const h = new Hierarchy(
        this.snapshot, this.levels, Uint32Array.from(this.ends), this.element.view(),
        this.to.view(), this.from.view());
    h.messages = this.messages;
    return h;
  }
}

/** What a job's settings default to (seed 1, as the C++ CLI). */
const JOB_SETTINGS = {
  algo: 'ml',
  energy: 'cvd',
  clusters: 0,
  seed: 1,
  options: {},
  levels: null,
  packed: true,
  label: '',
  device: 'auto',
  draco: {},
  payload: null,
  progress: null,
  timeoutSeconds: 0,
  chunkBytes: 1 << 20,
  detach: false
};
function jobSettings(settings) {
  const unknown = Object.keys(settings).filter((k) => !(k in JOB_SETTINGS));
  if (unknown.length) throw new TypeError(`unknown settings: ${unknown.join(', ')}`);
  return {...JOB_SETTINGS, ...settings};
}

/**
 * A JobSpec message (field names as in the proto) for `input`. `enums` has the names of
 * the proto's enum values: protobufjs would send an unknown name as 0 (the default).
 */
function jobSpec(
    enums, inputKind, input,
    {algo, energy, clusters, seed, options, levels, packed, label, device, detach}) {
  const enumName = (type, name) => {
    const value = `${type.toUpperCase()}_${name.toUpperCase().replace(/-/g, '_')}`;
    if (!enums[type].includes(value)) {
      const known = enums[type].slice(1).map((v) => v.slice(type.length + 1).toLowerCase());
      known.forEach((v, i) => (known[i] = v.replace(/_/g, '-')));
      const message = `no ${type} '${name}' in the proto (${known.join(', ')})`;
      throw new MlclustError(grpc.status.INVALID_ARGUMENT, message);
    }
    return value;
  };
  return {
    input_kind: inputKind,
    input_bytes: input.length,
    input_crc32: crc32(input),
    algorithm: enumName('Algorithm', algo === 'lnkmeans' ? 'ln-kmeans' : algo),
    energy: enumName('Energy', energy),
    clusters,
    seed,
    label,
    device,
    options: Object.fromEntries(Object.entries(options).map(([k, v]) => [k, String(v)])),
    levels_high: levels ? levels[0] : 0,
    levels_low: levels ? levels[1] : 0,
    packed_triplets: packed,  // an older server ignores it and sends the repeated fields
    detach,  // the call ends once the job is queued; watch(job_id) reads its levels
  };
}

class Client {
  /**
   * address "host:port" (plaintext). channelOptions: grpc-js channel options; by default
   * gRPC's own limits (4 MiB received per message), which the server keeps to.
   */
  constructor(address, {channelOptions = {}, protoFile = PROTO_FILE} = {}) {
    const definition = protoLoader.loadSync(
        protoFile, {keepCase: true, longs: Number, enums: String, defaults: true, oneofs: true});
    const Clustering = grpc.loadPackageDefinition(definition).mlclust.v1.Clustering;
    this.enums = Object.fromEntries(['Algorithm', 'Energy'].map(
        (type) => [type, definition[`mlclust.v1.${type}`].type.value.map((v) => v.name)]));
    this.stub = new Clustering(address, grpc.credentials.createInsecure(), channelOptions);
  }
  close() {
    this.stub.close();
  }

  /** GetServerInfo: version, device, algorithms with their energies and options, limits. */
  info({timeoutSeconds = 10} = {}) {
    return new Promise(
        (resolve, reject) => this.stub.GetServerInfo(
            {}, {deadline: Date.now() + 1000 * timeoutSeconds},
            (err, reply) =>
                (err ? reject(new MlclustError(err.code, err.details)) : resolve(reply))));
  }

  /**
   * Clusters a triangle mesh ({vertices: [x,y,z]... or flat, faces: [a,b,c]... or flat});
   * element ids are face indices. settings (JOB_SETTINGS has the defaults): algo ('ml', 'hc',
   * 'pml', 'emlo', 'bb', 'vsa'), energy ('cvd', 'planar', ...), clusters (JobSpec.clusters),
   * seed, options ({'p-percent': 10}), levels ([high, low]), draco ({method,
   * quantizationBits, faceIds} for encodeMesh) or payload (Draco bytes to send as they are),
   * progress(p) on every event before Done, timeoutSeconds, packed (raw uint32 triplets),
   * detach. Resolves to a Hierarchy with .accepted and .done (with detach, to the job's id
   * for watch); rejects with MlclustError.
   */
  async clusterMesh(mesh, settings = {}) {
    const s = jobSettings(settings);
    const input = s.payload || await encodeMesh(mesh, s.draco);
    return this.run(jobSpec(this.enums, 'INPUT_KIND_DRACO_MESH', input, s), input, s);
  }

  /**
   * Clusters points (m x dims numbers, row-major, sent as float32); element ids are row
   * indices. algo: 'ml', 'pml', 'hc', 'lnkmeans', 'kmeans', 'xmeans', 'bisecting'; the energy
   * is the within-cluster variance. Other settings as for clusterMesh.
   */
  async clusterPoints(points, dims, settings = {}) {
    const s = jobSettings({energy: 'variance', ...settings});
    const input = Buffer.alloc(4 * points.length);  // float32, little-endian
    points.forEach((v, i) => input.writeFloatLE(v, 4 * i));
    const spec = jobSpec(this.enums, 'INPUT_KIND_POINTS_F32', input, s);
    spec.point_dims = dims;
    return this.run(spec, input, s);
  }

  /** Runs one job: the spec with the first chunk, further chunks, then the events. */
  run(spec, input, {progress = null, timeoutSeconds = 0, chunkBytes = 1 << 20} = {}) {
    const call = this.stub.Run(deadline(timeoutSeconds));
    const result = receive(call, {progress, detach: spec.detach});
    (async () => {  // the upload, waiting whenever gRPC's send buffer is full
      for (let offset = 0; offset === 0 || offset < input.length; offset += chunkBytes) {
        const request = {chunk: input.subarray(offset, offset + chunkBytes)};
        if (offset === 0) request.spec = spec;
        if (!call.write(request)) await new Promise((r) => call.once('drain', r));
        if (call.settled) return;
      }
      call.end();
    })();
    return result;
  }

  /**
   * The levels of a job run with {detach: true} (which resolves to its id), while it runs or
   * after: level `fromLevel` of the job as the Hierarchy's level 0, then every later level.
   */
  watch(jobId, {fromLevel = 0, progress = null, timeoutSeconds = 0} = {}) {
    const request = {job_id: jobId, from_level: fromLevel};
    return receive(this.stub.Watch(request, deadline(timeoutSeconds)), {progress, absolute: true});
  }
}

function deadline(timeoutSeconds) {
  return timeoutSeconds ? {deadline: Date.now() + 1000 * timeoutSeconds} : {};
}

/**
 * A job's events from `call` (Run or Watch) into a Hierarchy (with .accepted and .done), or
 * the job's id for a detached Run. Sets call.settled once the promise is.
 */
function receive(call, {progress = null, detach = false, absolute = false}) {
  return new Promise((resolve, reject) => {
    const assembler = new Assembler(absolute);
    const state = {stage: '', fraction: 0, message: '', queuePosition: 0};
    let accepted = null;
    let done = null;
    let failed = null;
    const finish = (error, value) => {
      if (call.settled) return;
      call.settled = true;
      if (error) {
        call.cancel();
        reject(error);
      } else
        resolve(value);
    };
    call.on('data', (event) => {
      try {
        if (event.event === 'accepted') {
          accepted = event.accepted;
          Object.assign(state, {stage: 'queued', queuePosition: accepted.queue_position});
        } else if (event.event === 'progress') {
          Object.assign(state, {
            stage: event.progress.stage,
            fraction: event.progress.fraction,
            message: event.progress.message
          });
        } else if (event.event === 'done') {
          done = event.done;
        } else if (event.event === 'failed') {
          failed = new MlclustError(event.failed.code, event.failed.message);
        } else {
          assembler.add(event);
          state.stage = 'levels';
        }
        if (progress && !done && !failed) {
          const last = assembler.levels[assembler.levels.length - 1];
          progress({
            ...state,
            event: event.event,
            accepted,
            levelsReceived: assembler.levels.length,
            clusterCount: last ? last.clusterCount : 0
          });
        }
      } catch (error) {
        finish(error);
      }
    });
    call.on('error', (err) => finish(failed || new MlclustError(err.code, err.details)));
    call.on('end', () => {
      if (failed) return finish(failed);
      if (detach) {
        if (accepted && accepted.detached) return finish(null, accepted.job_id);
        return finish(new MlclustError(grpc.status.DATA_LOSS, 'the server did not detach the job'));
      }
      if (!done)
        return finish(new MlclustError(grpc.status.DATA_LOSS, 'the job ended without Done'));
      try {
        finish(null, Object.assign(assembler.finish(), {accepted, done}));
      } catch (error) {
        finish(error);
      }
    });
  });
}

module.exports = {
  version: require('./package.json').version,  // CMakeLists.txt's project() VERSION
  PROTO_FILE,
  Client,
  Hierarchy,
  MlclustError,
  encodeMesh,
  crc32,
  FACE_ID_NAME,
  Assembler,  // for tests
};
