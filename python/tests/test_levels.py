"""Hierarchy.labels(k) for a K that no level has: LevelNotFoundError naming the nearest
levels, or nearest=True taking the closest (a hierarchy built in code, no server)."""

import unittest

import numpy as np

import mlclust


def hierarchy():
    """Six elements: level 0 six clusters; 1: four; 2 and 3: three (as a single-level
    result after its start at the same count); 4: one."""
    element, to, frm, ends = [], [], [], [0]
    for moves in ([(1, 0, 1), (3, 2, 3)],  # 6 -> 4
                  [(5, 4, 5)],              # 4 -> 3
                  [(3, 4, 2)],              # 3 -> 3: element 3 moves to cluster 4
                  [(2, 0, 2), (3, 0, 4), (4, 0, 4), (5, 0, 4)]):  # 3 -> 1
        for e, t, f in moves:
            element.append(e)
            to.append(t)
            frm.append(f)
        ends.append(len(element))
    return mlclust.Hierarchy(np.arange(6), [6, 4, 3, 3, 1], [5.0, 4.0, 3.0, 2.0, 1.0],
                             [0, 1, 2, 3, 4], ends, element, to, frm)


class LevelsTest(unittest.TestCase):
    def test_an_existing_count_gives_its_last_level(self):
        h = hierarchy()
        np.testing.assert_array_equal(h.labels(4), [0, 0, 1, 1, 2, 3])
        self.assertEqual(h.level_for(3), 3)  # the result, not the start at the same count
        np.testing.assert_array_equal(h.labels(3), [0, 0, 1, 2, 2, 2])
        np.testing.assert_array_equal(h.labels_at(3), h.labels(3))
        self.assertEqual(h.energy(3), 2.0)

    def test_a_missing_count_names_the_nearest_levels(self):
        h = hierarchy()
        with self.assertRaises(mlclust.LevelNotFoundError) as e:
            h.labels(5)
        self.assertEqual(e.exception.k, 5)
        self.assertEqual(e.exception.nearest, [(6, 0), (4, 1)])
        self.assertEqual(str(e.exception), "no level has 5 clusters; the nearest: 6 (level 0) "
                         "and 4 (level 1); pass nearest=True to take the closest")
        self.assertIsInstance(e.exception, KeyError)  # level_for raised KeyError before
        with self.assertRaises(mlclust.LevelNotFoundError) as e:
            h.labels(2)
        self.assertEqual(e.exception.nearest, [(3, 3), (1, 4)])
        with self.assertRaises(mlclust.LevelNotFoundError) as e:
            h.energy(7)  # above the start: only the level below is near
        self.assertEqual(e.exception.nearest, [(6, 0)])
        self.assertIn("the nearest: 6 (level 0);", str(e.exception))
        with self.assertRaises(mlclust.LevelNotFoundError) as e:
            h.labels(0)
        self.assertEqual(e.exception.nearest, [(1, 4)])
        self.assertEqual(h.position, 0)  # a refusal does not move the cursor

    def test_nearest_takes_the_closest_count_and_fewer_clusters_on_a_tie(self):
        h = hierarchy()
        self.assertEqual(h.level_for(5, nearest=True), 1)  # 6 and 4 both 1 away: 4
        self.assertEqual(h.level_for(2, nearest=True), 4)  # 3 and 1 both 1 away: 1
        self.assertEqual(h.level_for(100, nearest=True), 0)
        np.testing.assert_array_equal(h.labels(5, nearest=True), h.labels(4))
        self.assertEqual(h.energy(7, nearest=True), 5.0)


if __name__ == "__main__":
    unittest.main()
