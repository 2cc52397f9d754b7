'use strict';
// The Node example (examples/node/mlclust.js) against a real server; run by
// node_client_test.sh, which starts the server and writes the C++ CLI's labels.
//   MLCLUST_SERVER=HOST:PORT MLCLUST_MESH=fandisk.off CLI_ML_LABELS=FILE (ml, level 50)
const assert = require('assert');
const fs = require('fs');
const path = require('path');
const {createRequire} = require('module');

const example = path.join(__dirname, '..', '..', 'examples', 'node');
const mlclust = require(path.join(example, 'mlclust'));
const {readOff} = require(path.join(example, 'cluster'));
const draco3d = createRequire(path.join(example, 'package.json'))('draco3d');
const grpc = createRequire(path.join(example, 'package.json'))('@grpc/grpc-js');

const client = new mlclust.Client(process.env.MLCLUST_SERVER);  // gRPC's default limits
const mesh = readOff(process.env.MLCLUST_MESH);
const numFaces = mesh.faces.length / 3;
let passed = 0;
let failed = 0;

async function check(name, body) {
  try {
    await body();
    passed++;
    console.log(`ok - ${name}`);
  } catch (error) {
    failed++;
    console.log(`not ok - ${name}\n${error.stack}`);
  }
}

/** Per decoded face, its mlclust_face_id (checked equal on the three corners). */
async function decodedFaceIds(bytes) {
  const M = await draco3d.createDecoderModule({});
  const buffer = new M.DecoderBuffer();
  buffer.Init(new Int8Array(bytes), bytes.length);
  const decoder = new M.Decoder();
  const decoded = new M.Mesh();
  assert.ok(decoder.DecodeBufferToMesh(buffer, decoded).ok(), 'draco3d decodes the payload');
  const id = decoder.GetAttributeIdByMetadataEntry(decoded, 'name', mlclust.FACE_ID_NAME);
  assert.ok(id >= 0, 'the payload has the face id attribute');
  const attribute = decoder.GetAttribute(decoded, id);
  const corners = new M.DracoInt32Array();
  const values = new M.DracoUInt32Array();
  decoder.GetAttributeUInt32ForAllPoints(decoded, attribute, values);
  const ids = [];
  for (let f = 0; f < decoded.num_faces(); f++) {
    decoder.GetFaceFromMesh(decoded, f, corners);
    const corner = [0, 1, 2].map((c) => values.GetValue(corners.GetValue(c)));
    assert.ok(corner[0] === corner[1] && corner[1] === corner[2], `face ${f}: one id per face`);
    ids.push(corner[0]);
  }
  [corners, values, decoded, decoder, buffer].forEach((o) => M.destroy(o));
  return ids;
}

function sameArrays(a, b, what) {
  assert.strictEqual(a.length, b.length, `${what}: lengths`);
  const first = a.findIndex((x, i) => x !== b[i]);
  assert.strictEqual(first, -1, `${what}: first difference at ${first}`);
}

/** Events as the server sends them (JobEvent, field names as in the proto). */
const snapshot = (first, labels, total) => ({
  event: 'snapshot',
  snapshot:
      {level: 0, cluster_count: 4, energy: 4, labels, first_element: first, total_elements: total}
});
const batch = (first, counts, ends, triplets, more = {}) => ({
  event: 'levels',
  levels: {
    first_level: first,
    cluster_count: counts,
    energy: counts,
    source_level: counts,
    triplet_end: ends,
    element: triplets.map((t) => t[0]),
    to_cluster: triplets.map((t) => t[1]),
    from_cluster: triplets.map((t) => t[2]),
    last_level_continues: false,
    packed_element: Buffer.alloc(0),
    packed_to_cluster: Buffer.alloc(0),
    packed_from_cluster: Buffer.alloc(0),
    ...more
  }
});
const packed = (values) => Buffer.from(Uint32Array.from(values).buffer);

(async () => {
  await check(
      'offline: split snapshot and split level joined; packed read; bad streams refused', () => {
        const assembler = new mlclust.Assembler();
        [snapshot(0, [0, 1], 4),
         snapshot(2, [2, 3], 4),
         batch(1, [3, 2], [1, 2], [[1, 0, 1], [3, 2, 3]], {last_level_continues: true}),
         batch(2, [2], [1], [], {
           packed_element: packed([2]),
           packed_to_cluster: packed([0]),
           packed_from_cluster: packed([2])
         }),
        ].forEach((e) => assembler.add(e));
        const h = assembler.finish();
        assert.deepStrictEqual(h.levels.map((l) => l.clusterCount), [4, 3, 2]);
        assert.deepStrictEqual(Array.from(h.labels(2, {compact: false})), [0, 0, 0, 2]);
        assert.deepStrictEqual(Array.from(h.labels(3, {compact: false})), [0, 0, 2, 3]);
        assert.deepStrictEqual(Array.from(h.labels(4)), [0, 1, 2, 3]);
        const refused = (events, pattern) => {
          const a = new mlclust.Assembler();
          assert.throws(
              () => events.forEach((e) => a.add(e)) || a.finish(),
              (e) => e.code === grpc.status.DATA_LOSS && pattern.test(e.details), `${pattern}`);
        };
        const start = snapshot(0, [0, 1, 2, 3], 4);
        refused([batch(1, [3], [1], [[1, 0, 1]])], /before the snapshot/);
        refused([start, batch(2, [3], [1], [[1, 0, 1]])], /expected 1/);
        refused([start, batch(1, [3], [2], [[1, 0, 1]])], /triplet_end/);
        refused([start, batch(1, [3], [1], [[9, 0, 1]])], /out of range/);
        refused(
            [start, batch(1, [3], [1], [[1, 0, 1]], {packed_element: packed([1])})], /both packed/);
        refused(
            [start, batch(1, [3], [1], [[1, 0, 1]], {last_level_continues: true})], /incomplete/);
        refused(
            [
              start, batch(1, [3], [1], [[1, 0, 1]], {last_level_continues: true}),
              batch(1, [2], [0], [])
            ],
            /another cluster count/);
      });

  await check('info: GetServerInfo lists the mesh algorithms', async () => {
    const info = await client.info();
    const ml =
        info.algorithms.find((a) => a.name === 'ml' && a.input_kind === 'INPUT_KIND_DRACO_MESH');
    assert.ok(ml && ml.hierarchy, 'ml is a mesh hierarchy');
    assert.ok(ml.options.some((o) => o.name === 'p-percent'), 'ml has p-percent');
  });

  let sequentialMl = null;
  await check('(a) sequential upload: labels equal the C++ CLI\'s for the same job', async () => {
    const stages = new Set();
    sequentialMl = await client.clusterMesh(
        mesh, {algo: 'ml', energy: 'cvd', progress: (p) => stages.add(p.stage)});
    assert.strictEqual(sequentialMl.accepted.draco_method, 'sequential');
    assert.strictEqual(sequentialMl.accepted.face_ids, false);
    for (const stage of ['queued', 'measures', 'cluster', 'levels'])
      assert.ok(stages.has(stage), stage);
    assert.strictEqual(sequentialMl.levels[0].clusterCount, numFaces);
    const cli = fs.readFileSync(process.env.CLI_ML_LABELS, 'utf8').trim().split('\n').map(Number);
    sameArrays(Array.from(sequentialMl.labels(50)), cli, 'ml labels at 50 against the CLI');
    assert.strictEqual(new Set(cli).size, 50);
  });

  await check(
      '(a) varint triplets give the levels packed triplets give; seeking back and forth',
      async () => {
        const varint = await client.clusterMesh(mesh, {algo: 'ml', packed: false});
        assert.strictEqual(varint.levels.length, sequentialMl.levels.length);
        sameArrays(
            varint.levels.map((l) => l.energy), sequentialMl.levels.map((l) => l.energy),
            'energies');
        for (const k of [1000, 50, 7]) {
          sameArrays(
              varint.labels(k, {compact: false}), sequentialMl.labels(k, {compact: false}),
              `level ${k}`);
        }
        const at50 = sequentialMl.labels(50);
        sequentialMl.labels(2);
        sequentialMl.labels(3000);
        sameArrays(sequentialMl.labels(50), at50, 'level 50 after stepping away and back');
      });

  await check(
      '(b) edgebreaker + quantisation + face ids (draco3d): labels map back exactly', async () => {
        const draco = {method: 'edgebreaker', quantizationBits: 14};
        const payload = await mlclust.encodeMesh(mesh, draco);
        const ids = await decodedFaceIds(payload);
        assert.strictEqual(ids.length, numFaces);
        const seen = new Uint8Array(numFaces);
        ids.forEach((id) => {
          assert.ok(id < numFaces && !seen[id], `id ${id} once`);
          seen[id] = 1;
        });
        assert.ok(
            ids.filter((id, f) => id === f).length < numFaces / 10,
            'edgebreaker reordered the faces');
        const edgebreaker = await client.clusterMesh(mesh, {algo: 'hc', payload});
        assert.strictEqual(edgebreaker.accepted.draco_method, 'edgebreaker');
        assert.strictEqual(edgebreaker.accepted.face_ids, true);
        // HC does not depend on the vertex order: the same quantised positions sent
        // sequentially (faces in order by themselves) give the same hierarchy.
        const sequential = await client.clusterMesh(
            mesh, {algo: 'hc', draco: {method: 'sequential', quantizationBits: 14}});
        assert.ok(payload.length * 3 < sequential.accepted.input_bytes, 'edgebreaker is smaller');
        sameArrays(
            edgebreaker.levels.map((l) => l.energy), sequential.levels.map((l) => l.energy),
            'energies');
        for (const k of [5000, 100, 12]) {
          sameArrays(edgebreaker.labels(k), sequential.labels(k), `hc labels at ${k}`);
        }
      });

  await check('(c) edgebreaker without the id attribute: Accepted says decoded order', async () => {
    const h = await client.clusterMesh(
        mesh, {algo: 'hc', draco: {method: 'edgebreaker', quantizationBits: 14, faceIds: false}});
    assert.strictEqual(h.accepted.draco_method, 'edgebreaker');
    assert.strictEqual(h.accepted.face_ids, false);
    assert.match(h.accepted.face_order, /decoded face order/);
    assert.strictEqual(h.labels(0, {level: 0}).length, numFaces);
  });

  await check(
      'draco3d welds vertices at equal positions (README says so), faces kept', async () => {
        // A square's two triangles with three vertices each: a seam along the diagonal.
        const square = {
          vertices: [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0],
          faces: [0, 1, 2, 3, 4, 5]
        };
        for (const method of ['sequential', 'edgebreaker']) {
          let measures = '';
          await client.clusterMesh(square, {
            algo: 'hc',
            draco: {method},
            progress: (p) => {
              if (p.stage === 'measures') measures = p.message;
            }
          });
          assert.match(measures, /^2 faces, 4 vertices/, method);
        }
      });

  await check('(d) a bad request: INVALID_ARGUMENT with the message', async () => {
    await assert.rejects(
        client.clusterMesh(mesh, {algo: 'ml', options: {'no-such-option': '1'}}),
        (e) => e instanceof mlclust.MlclustError && e.code === grpc.status.INVALID_ARGUMENT &&
            /no-such-option/.test(e.details));
    // A name the proto's enum lacks is refused before sending (protobufjs would send 0, ML).
    await assert.rejects(
        client.clusterMesh(mesh, {algo: 'mll'}),
        (e) => e.code === grpc.status.INVALID_ARGUMENT && /no Algorithm 'mll'/.test(e.details));
    // Three faces on edge 0-1: a non-manifold edge.
    const fin = {
      vertices: [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1],
      faces: [0, 1, 2, 1, 0, 3, 0, 1, 4]
    };
    await assert.rejects(
        client.clusterMesh(fin, {algo: 'ml'}),
        (e) => e.code === grpc.status.INVALID_ARGUMENT && e.codeName === 'INVALID_ARGUMENT' &&
            /non-manifold edge/.test(e.details));
  });

  await check(
      'a level over 4 MiB arrives split (default limits): k-means on 10^6 points', async () => {
        let seed = 7;
        const random = () => (seed = (seed * 1103515245 + 12345) % 2147483648) / 2147483648;
        const points = new Float32Array(3 * 1000000).map(random);
        const h = await client.clusterPoints(
            points, 3, {algo: 'kmeans', clusters: 8, options: {init: 'random'}});
        assert.strictEqual(h.levels.length, 2);
        assert.ok(
            h.element.length * 12 > 4 << 20, `${h.element.length} triplets: over 4 MiB packed`);
        assert.ok(h.messages.continued >= 1, 'a level continued in the next batch');
        // The labels rebuilt from the split level give the energy the server reports (the
        // within-cluster sum of squared distances), at both levels.
        for (const level of [0, 1]) {
          const labels = h.labels(0, {level});
          const sums = new Float64Array(4 * 8);
          labels.forEach((l, i) => {
            for (let d = 0; d < 3; d++) sums[4 * l + d] += points[3 * i + d];
            sums[4 * l + 3]++;
          });
          let energy = 0;
          labels.forEach((l, i) => {
            for (let d = 0; d < 3; d++)
              energy += (points[3 * i + d] - sums[4 * l + d] / sums[4 * l + 3]) ** 2;
          });
          const reported = h.levels[level].energy;
          assert.ok(
              Math.abs(energy - reported) <= 1e-6 * reported,
              `level ${level}: energy ${energy}, reported ${reported}`);
        }
      });

  client.close();
  console.log(`${passed} passed, ${failed} failed`);
  process.exit(failed ? 1 : 0);
})();
