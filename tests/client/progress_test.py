"""The wire contract's Progress.fraction and Accepted's face order, against a real server
(`mlclust serve`), with the raw generated stubs (a foreign client sees the same).

Run by ctest (tests/CMakeLists.txt, CliWiringProgress) as
    MLCLUST_BIN=build/client/mlclust MLCLUST_DATA=data PYTHONPATH=build/python \
        /usr/bin/python3 -m unittest tests/client/progress_test.py -v
"""

import os
import sys
import unittest

import grpc
import numpy as np

import mlclust
from mlclust import _draco
from mlclust.v1 import mlclust_pb2 as pb
from mlclust.v1 import mlclust_pb2_grpc as pb_grpc

# The server set-up shared with the Python package's tests (python/tests/served.py).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..",
                                "python", "tests"))
from served import DATA, ServedTestCase  # noqa: E402

STAGES = {"queued", "decode", "measures", "seed", "cluster"}


class ProgressTest(ServedTestCase):
    @classmethod
    def connect(cls):
        cls.channel = grpc.insecure_channel(cls.address)  # default limits
        cls.stub = pb_grpc.ClusteringStub(cls.channel)
        cls.vertices, cls.faces = mlclust.read_mesh(os.path.join(DATA, "fandisk.off"))

    @classmethod
    def disconnect(cls):
        if hasattr(cls, "channel"):
            cls.channel.close()

    def run_job(self, spec, payload):
        spec.input_bytes = len(payload)
        events = list(self.stub.Run(iter([pb.RunRequest(spec=spec, chunk=payload)])))
        self.assertTrue(events[-1].final)
        self.assertEqual(events[-1].WhichOneof("event"), "done", events[-1])
        return events

    def mesh_payload(self, method):
        payload, code, message = _draco.encode_mesh(
            self.vertices, self.faces, method=method, face_ids=method == "edgebreaker")
        self.assertEqual(code, 0, message)
        return payload

    def check_progress(self, events):
        """Every fraction in [0, 1], stages from the list in the proto, the cluster stage's
        fractions never decreasing and ending at 1."""
        progress = [e.progress for e in events if e.WhichOneof("event") == "progress"]
        for p in progress:
            self.assertIn(p.stage, STAGES, p)
            self.assertGreaterEqual(p.fraction, 0, p)
            self.assertLessEqual(p.fraction, 1, p)
        cluster = [p.fraction for p in progress if p.stage == "cluster"]
        self.assertEqual(cluster, sorted(cluster))
        self.assertEqual(cluster[-1], 1.0)
        return progress

    def run_mesh_job(self, spec, method):
        """Runs `spec` on the mesh encoded with Draco's `method`, checks its progress
        events; returns them and the job's Accepted."""
        events = self.run_job(spec, self.mesh_payload(method))
        return self.check_progress(events), events[0].accepted

    def test_mesh_hierarchy_fraction_and_decoded_order(self):
        spec = pb.JobSpec(input_kind=pb.INPUT_KIND_DRACO_MESH, algorithm=pb.ALGORITHM_HC)
        progress, accepted = self.run_mesh_job(spec, "sequential")
        measures = [p for p in progress if p.stage == "measures"]
        self.assertEqual(measures[-1].fraction, 1.0)
        self.assertFalse(accepted.face_ids)
        self.assertEqual(accepted.draco_method, "sequential")
        self.assertIn("decoded face order", accepted.face_order)

    def test_mesh_single_level_with_face_ids(self):
        spec = pb.JobSpec(input_kind=pb.INPUT_KIND_DRACO_MESH, algorithm=pb.ALGORITHM_EMLO,
                          clusters=20)
        _, accepted = self.run_mesh_job(spec, "edgebreaker")
        self.assertTrue(accepted.face_ids)
        self.assertEqual(accepted.draco_method, "edgebreaker")
        self.assertIn("mlclust_face_id", accepted.face_order)

    def test_vsa_iterations_report_their_share(self):
        spec = pb.JobSpec(input_kind=pb.INPUT_KIND_DRACO_MESH, algorithm=pb.ALGORITHM_VSA,
                          clusters=20, options={"max-iterations": "4"})
        progress = self.check_progress(self.run_job(spec, self.mesh_payload("sequential")))
        cluster = [p.fraction for p in progress if p.stage == "cluster"]
        for share in (0.25, 0.5, 0.75):
            self.assertIn(share, cluster)

    def test_points_divisive_hierarchy_and_xmeans(self):
        rng = np.random.default_rng(2)
        x = np.concatenate([c + rng.normal(size=(200, 3)) for c in
                            ([0, 0, 0], [30, 0, 0], [0, 30, 0])]).astype(np.float32)
        for algorithm in (pb.ALGORITHM_BISECTING, pb.ALGORITHM_XMEANS):
            spec = pb.JobSpec(input_kind=pb.INPUT_KIND_POINTS_F32, point_dims=3,
                              algorithm=algorithm, clusters=6 if algorithm ==
                              pb.ALGORITHM_BISECTING else 1)
            events = self.run_job(spec, x.tobytes())
            self.check_progress(events)
            accepted = events[0].accepted
            self.assertFalse(accepted.face_ids)
            self.assertEqual(accepted.face_order, "")
            if algorithm == pb.ALGORITHM_XMEANS:
                self.assertEqual(events[-1].done.final_clusters, 3)


if __name__ == "__main__":
    unittest.main()
