#!/usr/bin/env node
'use strict';
// node cluster.js MESH.off --server ADDR [--algo ml] [-k K] [--energy cvd] [--upload
//   sequential|edgebreaker|edgebreaker-no-ids] [--quantize BITS] [--option NAME=VALUE]...
//   [--labels FILE] [--accepted] [--varint] [--quiet]
// node cluster.js --info --server ADDR
// Clusters an OFF mesh through an mlclust server and prints a summary of the levels;
// --labels FILE writes the level with K clusters, one line per face (as `mlclust mesh`).
const fs = require('fs');
const mlclust = require('./mlclust');

/** An OFF file's {vertices (flat), faces (flat)}; polygons are fanned into triangles. */
function readOff(file) {
  const words = fs.readFileSync(file, 'utf8').replace(/#[^\n]*/g, '').split(/\s+/).filter(Boolean);
  if (!/^C?N?OFF$/.test(words[0])) throw new Error(`${file}: not an OFF file`);
  const [numVertices, numFaces] = [Number(words[1]), Number(words[2])];
  let at = 4;
  const vertices = new Float32Array(words.slice(at, at += 3 * numVertices).map(Number));
  const faces = [];
  for (let f = 0; f < numFaces; f++) {
    const n = Number(words[at]);
    const corners = words.slice(at + 1, at + 1 + n).map(Number);
    for (let c = 1; c + 1 < n; c++) faces.push(corners[0], corners[c], corners[c + 1]);
    at += 1 + n;
  }
  return {vertices, faces: Uint32Array.from(faces)};
}

const VALUE_FLAGS = {
  '--server': 'server',
  '--algo': 'algo',
  '--energy': 'energy',
  '-k': 'k',
  '--clusters': 'k',
  '--upload': 'upload',
  '--quantize': 'quantize',
  '--labels': 'labels'
};
const SWITCHES = ['--info', '--accepted', '--varint', '--quiet'];

function parseArgs(argv) {
  const args = {
    server: 'localhost:50051',
    algo: 'ml',
    energy: 'cvd',
    k: '0',
    upload: 'sequential',
    quantize: '0',
    options: {},
    labels: '',
    mesh: ''
  };
  for (let i = 0; i < argv.length; i++) {
    const flag = argv[i];
    if (flag in VALUE_FLAGS || flag === '--option') {
      if (i + 1 >= argv.length) throw new Error(`${flag} needs a value`);
      const value = argv[++i];
      if (flag !== '--option') {
        args[VALUE_FLAGS[flag]] = value;
      } else {
        const [name, ...rest] = value.split('=');
        args.options[name] = rest.join('=');
      }
    } else if (SWITCHES.includes(flag)) {
      args[flag.slice(2)] = true;
    } else if (!flag.startsWith('-') && !args.mesh) {
      args.mesh = flag;
    } else {
      throw new Error(`unknown argument ${flag}`);
    }
  }
  [args.k, args.quantize] = [args.k, args.quantize].map((text) => {
    if (!/^\d+$/.test(text)) throw new Error(`'${text}' is not a non-negative integer`);
    return Number(text);
  });
  if (!args.info && !args.mesh)
    throw new Error('usage: cluster.js MESH.off --server ADDR [--algo ml] [-k K]');
  if (!['sequential', 'edgebreaker', 'edgebreaker-no-ids'].includes(args.upload)) {
    throw new Error(`--upload ${args.upload}: sequential, edgebreaker or edgebreaker-no-ids`);
  }
  return args;
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  const client = new mlclust.Client(args.server);
  try {
    const info = await client.info();
    if (args.info) {
      console.log(`mlclust ${info.version} (${info.build}); GL: ${info.gl_renderer || 'none'}`);
      for (const a of info.algorithms) {
        console.log(
            `${a.input_kind === 'INPUT_KIND_DRACO_MESH' ? 'mesh' : 'points'} ${a.name}: ` +
            `${a.title}; options: ${a.options.map((o) => o.name).join(', ') || 'none'}`);
      }
      return;
    }
    // Hierarchies compute every level (-k picks the one written); others compute K.
    const algorithm = info.algorithms.find(
        (a) => a.name === args.algo && a.input_kind === 'INPUT_KIND_DRACO_MESH');
    if (!algorithm) throw new Error(`the server has no mesh algorithm '${args.algo}'`);
    const clock = [Date.now()];
    const mesh = readOff(args.mesh);
    clock.push(Date.now());
    const payload = await mlclust.encodeMesh(mesh, {
      quantizationBits: args.quantize,
      method: args.upload === 'sequential' ? 'sequential' : 'edgebreaker',
      faceIds: args.upload === 'edgebreaker'
    });
    clock.push(Date.now());
    let lastStage = '';
    const h = await client.clusterMesh(null, {
      algo: args.algo,
      energy: args.energy,
      payload,
      clusters: algorithm.hierarchy ? 0 : args.k,
      options: args.options,
      packed: !args.varint,
      progress: (p) => {
        if (!args.quiet && p.stage !== lastStage) console.error(`[${p.stage}] ${p.message}`);
        lastStage = p.stage;
      }
    });
    const a = h.accepted;
    if (args.accepted) {
      console.log(
          `accepted: job ${a.job_id}, ${a.input_bytes} bytes, draco_method ` +
          `${a.draco_method}, face_ids ${a.face_ids}, face_order: ${a.face_order}`);
    }
    clock.push(Date.now());
    const first = h.levels[0];
    const last = h.levels[h.levels.length - 1];
    console.log(
        `${h.levels.length} levels, ${first.clusterCount} -> ${last.clusterCount} ` +
        `clusters, ${h.element.length} triplets, ${h.done.seconds_running.toFixed(3)} s on ${
            h.done.device}`);
    if (!args.quiet) {
      const m = h.messages;
      const s = (i) => ((clock[i + 1] - clock[i]) / 1000).toFixed(2);
      console.error(
          `read ${s(0)} s, Draco ${payload.length} bytes in ${s(1)} s, job ${s(2)} s ` +
          `(queued ${h.done.seconds_queued.toFixed(2)}, running ${
              h.done.seconds_running.toFixed(2)}); ` +
          `${m.snapshot} snapshot and ${m.levels} level messages (${m.continued} continued)`);
    }
    if (args.labels) {
      const labels = args.k ? h.labels(args.k) : h.labels(0, {level: h.levels.length - 1});
      fs.writeFileSync(args.labels, labels.join('\n') + '\n');
    }
  } finally {
    client.close();
  }
}

if (require.main === module) {
  main().catch((error) => {
    console.error(`error: ${error.message}`);
    process.exit(error instanceof mlclust.MlclustError ? 1 : 2);
  });
}
module.exports = {readOff};
