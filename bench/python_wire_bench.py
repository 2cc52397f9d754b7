#!/usr/bin/env python3
"""The Python client's cost of reading level batches (issue 13): varint vs packed triplets.

Builds LevelBatch events of BATCH triplets with face ids and cluster ids below FACES (8
triplets a level, as HC on armadillo_1m), then times mlclust._wire.parse_bulk_event over
them, median of 5.
    PYTHONPATH=build/python /usr/bin/python3 bench/python_wire_bench.py [FACES] [TRIPLETS]
"""
import statistics
import sys
import time

import numpy as np

from mlclust import _wire
from mlclust.v1 import mlclust_pb2 as pb

faces = int(sys.argv[1]) if len(sys.argv) > 1 else 832000
total = int(sys.argv[2]) if len(sys.argv) > 2 else 6920365
batch = 65536
rng = np.random.default_rng(1)
events = {"varint": [], "packed": []}
for start in range(0, total, batch):
    m = min(batch, total - start)
    element = rng.integers(0, faces, size=m).astype(np.uint32)
    to = rng.integers(0, faces, size=m).astype(np.uint32)
    frm = rng.integers(0, faces, size=m).astype(np.uint32)
    ends = np.arange(8, m + 8, 8, dtype=np.uint32).clip(max=m)
    levels = dict(first_level=1 + start // 8, cluster_count=rng.integers(1, faces, size=len(ends)),
                  energy=rng.normal(size=len(ends)), triplet_end=ends,
                  source_level=rng.integers(1, faces, size=len(ends)))
    common = {k: np.asarray(v).tolist() if k != "first_level" else v for k, v in levels.items()}
    events["varint"].append(pb.JobEvent(levels=pb.LevelBatch(
        **common, element=element.tolist(), to_cluster=to.tolist(),
        from_cluster=frm.tolist())).SerializeToString())
    events["packed"].append(pb.JobEvent(levels=pb.LevelBatch(
        **common, packed_element=element.tobytes(), packed_to_cluster=to.tobytes(),
        packed_from_cluster=frm.tobytes())).SerializeToString())
for kind, data in events.items():
    times = []
    for _ in range(5):
        t = time.perf_counter()
        for d in data:
            parsed = _wire.parse_bulk_event(d)
            assert parsed is not None and parsed[0] == "levels"
        times.append(time.perf_counter() - t)
    seconds = statistics.median(times)
    size = sum(len(d) for d in data)
    print(f"{kind}: {total} triplets in {len(data)} batches, {size / 1e6:.1f} MB; "
          f"parse {seconds:.3f} s = {total / seconds / 1e6:.1f} M triplets/s")
