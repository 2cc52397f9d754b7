"""The numpy fast path for level batches and snapshots reads what protobuf reads."""

import unittest

import numpy as np

from mlclust import _wire
from mlclust.v1 import mlclust_pb2 as pb


def varint(value):
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        out.append(byte | (0x80 if value else 0))
        if not value:
            return bytes(out)


class WireTest(unittest.TestCase):
    def test_packed_uint32_of_every_length(self):
        rng = np.random.default_rng(1)
        values = np.concatenate([
            [0, 1, 127, 128, 16383, 16384, 2**21 - 1, 2**21, 2**28 - 1, 2**28, 2**32 - 1],
            rng.integers(0, 2**32, size=5000, dtype=np.uint64),
            rng.integers(0, 200, size=5000)]).astype(np.uint32)
        data = b"".join(varint(int(v)) for v in values)
        np.testing.assert_array_equal(_wire.packed_uint32(data), values)
        small = np.arange(100, dtype=np.uint32)
        np.testing.assert_array_equal(_wire.packed_uint32(bytes(small.astype(np.uint8))), small)
        with self.assertRaises(ValueError):
            _wire.packed_uint32(b"\x80")  # truncated
        with self.assertRaises(ValueError):
            _wire.packed_uint32(varint(2**32))  # over 32 bits

    def test_level_batches_and_snapshots_match_protobuf(self):
        rng = np.random.default_rng(2)
        for trial in range(20):
            n = int(rng.integers(0, 30))
            m = int(rng.integers(0, 400))
            ends = np.sort(rng.integers(0, m + 1, size=n)).astype(np.uint32)
            event = pb.JobEvent(levels=pb.LevelBatch(
                first_level=int(rng.integers(1, 2**31)),
                cluster_count=rng.integers(0, 2**32, size=n, dtype=np.uint64).tolist(),
                energy=rng.normal(size=n).tolist(),
                triplet_end=ends.tolist(),
                element=rng.integers(0, 2**32, size=m, dtype=np.uint64).tolist(),
                to_cluster=rng.integers(0, 300, size=m).tolist(),
                from_cluster=rng.integers(0, 2**20, size=m).tolist(),
                source_level=rng.integers(0, 2**32, size=n if trial % 2 else 0,
                                          dtype=np.uint64).tolist()))
            kind, fast = _wire.parse_bulk_event(event.SerializeToString())
            self.assertEqual(kind, "levels")
            b = event.levels
            self.assertEqual(fast["first_level"], b.first_level)
            for name in ("cluster_count", "energy", "triplet_end", "element", "to_cluster",
                         "from_cluster", "source_level"):
                np.testing.assert_array_equal(fast[name], np.array(getattr(b, name)), name)
        snapshot = pb.JobEvent(snapshot=pb.LevelSnapshot(
            level=3, cluster_count=7, energy=0.125, labels=[5, 2**31, 0, 7], first_element=9,
            total_elements=13))
        kind, fast = _wire.parse_bulk_event(snapshot.SerializeToString())
        self.assertEqual(kind, "snapshot")
        self.assertEqual(fast["energy"], 0.125)
        self.assertEqual((fast["level"], fast["cluster_count"], fast["first_element"],
                          fast["total_elements"]), (3, 7, 9, 13))
        np.testing.assert_array_equal(fast["labels"], [5, 2**31, 0, 7])

    def test_packed_triplets_read_as_the_repeated_ones(self):
        # JobSpec.packed_triplets (issue 13): LevelBatch fields 10-12, raw little-endian uint32.
        rng = np.random.default_rng(3)
        element = rng.integers(0, 2**32, size=257, dtype=np.uint64).astype(np.uint32)
        to = rng.integers(0, 300, size=257).astype(np.uint32)
        frm = rng.integers(0, 2**20, size=257).astype(np.uint32)
        packed = pb.JobEvent(levels=pb.LevelBatch(
            first_level=4, cluster_count=[9, 8], energy=[0.5, 0.25], triplet_end=[100, 257],
            packed_element=element.astype("<u4").tobytes(),
            packed_to_cluster=to.astype("<u4").tobytes(),
            packed_from_cluster=frm.astype("<u4").tobytes()))
        kind, fast = _wire.parse_bulk_event(packed.SerializeToString())
        self.assertEqual(kind, "levels")
        np.testing.assert_array_equal(fast["element"], element)
        np.testing.assert_array_equal(fast["to_cluster"], to)
        np.testing.assert_array_equal(fast["from_cluster"], frm)
        np.testing.assert_array_equal(fast["triplet_end"], [100, 257])
        # Both kinds in one batch, or a length that is not whole uint32s: left to protobuf.
        both = pb.JobEvent()
        both.CopyFrom(packed)
        both.levels.element.append(1)
        self.assertIsNone(_wire.parse_bulk_event(both.SerializeToString()))
        broken = pb.JobEvent()
        broken.CopyFrom(packed)
        broken.levels.packed_element = b"\x01\x02\x03"
        self.assertIsNone(_wire.parse_bulk_event(broken.SerializeToString()))

    def test_anything_else_is_left_to_protobuf(self):
        self.assertIsNone(_wire.parse_bulk_event(
            pb.JobEvent(accepted=pb.Accepted(job_id="j")).SerializeToString()))
        self.assertIsNone(_wire.parse_bulk_event(
            pb.JobEvent(done=pb.Done(levels=3), final=True).SerializeToString()))
        # An unpacked repeated field (legal protobuf, not what our server sends).
        batch = varint(2 << 3 | 0) + varint(5)  # cluster_count as one unpacked varint
        event = varint(4 << 3 | 2) + varint(len(batch)) + batch
        self.assertIsNone(_wire.parse_bulk_event(event))
        self.assertEqual(list(pb.JobEvent.FromString(event).levels.cluster_count), [5])
        self.assertIsNone(_wire.parse_bulk_event(b"\x22\x05\x12"))  # truncated


if __name__ == "__main__":
    unittest.main()


class SplitLevelTest(unittest.TestCase):
    """A level split across batches (LevelBatch.last_level_continues) is joined."""

    def assemble(self, batches, as_bytes):
        from mlclust.client import _Assembler
        assembler = _Assembler(None)
        events = [pb.JobEvent(snapshot=pb.LevelSnapshot(
            level=0, cluster_count=4, labels=[0, 1, 2, 3], total_elements=4))]
        events += [pb.JobEvent(levels=b) for b in batches]
        events.append(pb.JobEvent(done=pb.Done(levels=3), final=True))
        for event in events:
            if as_bytes:
                assembler.add_bytes(event.SerializeToString())
            else:
                assembler.add(event)
        return assembler.finish()

    def test_split_and_whole_levels_give_the_same_hierarchy(self):
        whole = [pb.LevelBatch(first_level=1, cluster_count=[3, 2], energy=[2.0, 1.0],
                               triplet_end=[2, 3], element=[0, 1, 2], to_cluster=[3, 3, 3],
                               from_cluster=[0, 1, 2], source_level=[1, 2])]
        split = [pb.LevelBatch(first_level=1, cluster_count=[3], energy=[2.0], triplet_end=[1],
                               element=[0], to_cluster=[3], from_cluster=[0], source_level=[1],
                               last_level_continues=True),
                 pb.LevelBatch(first_level=1, cluster_count=[3, 2], energy=[2.0, 1.0],
                               triplet_end=[1, 2], element=[1, 2], to_cluster=[3, 3],
                               from_cluster=[1, 2], source_level=[1, 2])]
        for as_bytes in (False, True):
            expected = self.assemble(whole, as_bytes)
            joined = self.assemble(split, as_bytes)
            self.assertEqual(len(joined.levels), 3)
            self.assertEqual([l.cluster_count for l in joined.levels], [4, 3, 2])
            for k in (4, 3, 2):
                np.testing.assert_array_equal(joined.labels(k), expected.labels(k))

    def test_a_job_that_ends_inside_a_split_level_is_data_loss(self):
        import mlclust
        half = pb.LevelBatch(first_level=1, cluster_count=[3], energy=[2.0], triplet_end=[1],
                             element=[0], to_cluster=[3], from_cluster=[0], source_level=[1],
                             last_level_continues=True)
        with self.assertRaises(mlclust.Error):
            self.assemble([half], True)
