"""The clustering hierarchy a job sends: a snapshot of labels, then levels as triplets.

Level 0 is the first level the server sent (the snapshot). Level i > 0 lists the
elements whose cluster changed from level i - 1 as triplets (element, to_cluster,
from_cluster); applying `to` steps forward, applying `from` steps back. Nothing is
recomputed to look at another level.
"""

from typing import NamedTuple, Optional

import numpy as np


class Level(NamedTuple):
    index: int          # 0 = the snapshot
    cluster_count: int
    energy: float
    source_level: int   # the engine's own level number (differs with a level range)


def compact_labels(labels):
    """Renumbers labels 0..K-1 in order of first appearance (as the CLI's --labels)."""
    labels = np.asarray(labels)
    if labels.size == 0:
        return labels.astype(np.uint32)
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.uint32)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size, dtype=np.uint32)
    return rank[inverse]


class LevelNotFoundError(KeyError):
    """No level has the asked number of clusters. `k` is what was asked; `nearest` the
    (cluster_count, level) of the nearest levels, the one above k then the one below (one
    or none where the hierarchy ends on that side)."""

    def __init__(self, k, nearest):
        self.k = k
        self.nearest = list(nearest)
        super().__init__(k)

    def __str__(self):
        if not self.nearest:
            return f"no level has {self.k} clusters (the hierarchy has no levels)"
        named = " and ".join(f"{count} (level {level})" for count, level in self.nearest)
        return (f"no level has {self.k} clusters; the nearest: {named}; pass nearest=True "
                "to take the closest")


class Hierarchy:
    """Every level of one job, with a cursor that steps between levels.

    levels: the levels as Level tuples; cluster_counts / energies as numpy arrays.
    labels(k): compact labels (0..k-1) of the level with k clusters (LevelNotFoundError
    naming the nearest levels when none has k; nearest=True takes the closest).
    seek(level) / step(n): moves the cursor by applying triplets; current_labels() gives
    the server's cluster ids at the cursor.
    done: the job's Done message (device, times, elbows, BIC); job_id: the server's id.
    polygons: triangles per polygon where mlclust.cluster_mesh split polygons, else None.
    """

    polygons = None

    def __init__(self, snapshot, cluster_counts, energies, source_levels, level_end,
                 element, to_cluster, from_cluster, done=None, job_id=""):
        self._snapshot = np.asarray(snapshot, dtype=np.uint32)
        self.cluster_counts = np.asarray(cluster_counts, dtype=np.int64)
        self.energies = np.asarray(energies, dtype=np.float64)
        self._source_levels = np.asarray(source_levels, dtype=np.int64)
        self._end = np.asarray(level_end, dtype=np.int64)
        self._element = np.asarray(element, dtype=np.uint32)
        self._to = np.asarray(to_cluster, dtype=np.uint32)
        self._from = np.asarray(from_cluster, dtype=np.uint32)
        self.done = done
        self.job_id = job_id
        self._position = 0
        self._current = self._snapshot.copy()
        if not (len(self.cluster_counts) == len(self.energies) == len(self._end)
                == len(self._source_levels)) or len(self._end) == 0:
            raise ValueError("a hierarchy needs one count, energy and end per level")

    # --- levels -------------------------------------------------------------------------
    @property
    def num_elements(self) -> int:
        return int(self._snapshot.size)

    @property
    def num_triplets(self) -> int:
        return int(self._end[-1])

    @property
    def levels(self):
        return [Level(i, int(c), float(e), int(s)) for i, (c, e, s) in enumerate(
            zip(self.cluster_counts, self.energies, self._source_levels))]

    def __len__(self):
        return len(self.cluster_counts)

    def __iter__(self):
        """Yields (Level, labels) from the snapshot on, stepping the cursor forward;
        labels is a read-only view of the server's ids, valid until the cursor moves."""
        for i in range(len(self)):
            self.seek(i)
            yield (Level(i, int(self.cluster_counts[i]), float(self.energies[i]),
                         int(self._source_levels[i])), self.current_labels())

    def level_for(self, k: int, nearest: bool = False) -> int:
        """The level with k clusters: the last with exactly k (a single-level algorithm's
        result follows its start at the same k). When no level has k: LevelNotFoundError
        naming the nearest levels above and below k, or with nearest=True the level whose
        count is closest to k (the one with fewer clusters on a tie; PML may skip counts)."""
        k = int(k)
        exact = np.flatnonzero(self.cluster_counts == k)
        if exact.size:
            return int(exact[-1])
        above = np.flatnonzero(self.cluster_counts > k)
        below = np.flatnonzero(self.cluster_counts < k)
        # The closest count on each side, each at the last level that has it (as for k).
        candidates = []
        for side, pick in ((above, np.min), (below, np.max)):
            if side.size:
                count = int(pick(self.cluster_counts[side]))
                candidates.append((count, int(np.flatnonzero(self.cluster_counts == count)[-1])))
        if nearest and candidates:
            return min(candidates, key=lambda c: (abs(c[0] - k), c[0]))[1]
        raise LevelNotFoundError(k, candidates)

    def energy(self, k: int, nearest: bool = False) -> float:
        """The energy of the level with k clusters (level_for(k, nearest))."""
        return float(self.energies[self.level_for(k, nearest)])

    def labels(self, k: Optional[int] = None, *, level: Optional[int] = None,
               compact: bool = True, nearest: bool = False):
        """Labels of every element at the level with k clusters (or at `level`), as
        0..K-1 in order of first appearance (compact=True) or the server's ids. Moves the
        cursor there. A k that no level has raises LevelNotFoundError naming the nearest
        levels; nearest=True takes the closest of them instead (level_for)."""
        if (k is None) == (level is None):
            raise ValueError("give k or level")
        self.seek(self.level_for(k, nearest) if level is None else level)
        labels = self._current.copy()
        return compact_labels(labels) if compact else labels

    def labels_at(self, k: int, nearest: bool = False):
        """labels(k): the compact labels of the level with k clusters (the estimators'
        hierarchy_.labels_at(k))."""
        return self.labels(k, nearest=nearest)

    def triplets(self, level: int):
        """(element, to_cluster, from_cluster) arrays of `level` (empty for level 0)."""
        self._check(level)
        if level == 0:
            empty = np.empty(0, dtype=np.uint32)
            return empty, empty, empty
        r = slice(self._end[level - 1], self._end[level])
        return self._element[r], self._to[r], self._from[r]

    # --- the cursor ---------------------------------------------------------------------
    @property
    def position(self) -> int:
        return self._position

    def current_labels(self):
        """The server's cluster ids at the cursor (a read-only view)."""
        view = self._current.view()
        view.flags.writeable = False
        return view

    def step(self, n: int = 1) -> int:
        """Moves the cursor n levels (negative: back); returns the new level."""
        return self.seek(self._position + n)

    def seek(self, level: int) -> int:
        """Moves the cursor to `level` by applying the triplets in between: forwards each
        element takes the `to` of its last move, backwards the `from` of its first."""
        self._check(level)
        if level > self._position:
            r = slice(self._end[self._position], self._end[level])
            elements = self._element[r][::-1]
            unique, first = np.unique(elements, return_index=True)
            self._current[unique] = self._to[r][::-1][first]
        elif level < self._position:
            r = slice(self._end[level], self._end[self._position])
            unique, first = np.unique(self._element[r], return_index=True)
            self._current[unique] = self._from[r][first]
        self._position = level
        return level

    def _check(self, level):
        if not 0 <= level < len(self):
            raise IndexError(f"level {level} is not in 0..{len(self) - 1}")


def labels_per_polygon(labels, polygons):
    """One label per polygon from labels per face (each polygon's first triangle's; with
    cluster_mesh(..., polygons=...) all its triangles have it). `polygons` as for
    cluster_mesh: the triangles of each polygon, in face order."""
    counts = np.asarray(polygons, dtype=np.int64).reshape(-1)
    first = np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.int64)
    return np.asarray(labels)[first]
