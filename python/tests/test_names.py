"""The Python client's names for algorithms and energies (mlclust.ALGORITHMS, ENERGIES)
cover every value of the proto's enums: a value added to the wire without its Python name
fails here (CONTRIBUTING.md, "How to add an energy / an algorithm")."""

import unittest

import mlclust
from mlclust.v1 import mlclust_pb2 as pb


class NamesTest(unittest.TestCase):
    def check(self, names, enum, prefix, separator):
        """`names` maps every non-zero value of `enum` by the registry's name: the enum's
        name without `prefix`, in lower case, `separator` for its underscores."""
        wire = {value for _, value in enum.items() if value != 0}
        self.assertEqual(set(names.values()), wire)
        for name, value in names.items():
            suffix = enum.Name(value)[len(prefix):]
            self.assertEqual(name, suffix.lower().replace("_", separator))

    def test_every_wire_algorithm_has_its_name(self):
        # ALGORITHM_LN_KMEANS is "lnkmeans".
        self.check(mlclust.ALGORITHMS, pb.Algorithm, "ALGORITHM_", "")

    def test_every_wire_energy_has_its_name(self):
        # ENERGY_CVD_ADAPTIVE is "cvd-adaptive".
        self.check(mlclust.ENERGIES, pb.Energy, "ENERGY_", "-")


if __name__ == "__main__":
    unittest.main()
