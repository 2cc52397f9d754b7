"""The estimators (mlclust.MultilevelClustering, LocalNeighboursKMeans, KMeans, XMeans) in
scikit-learn's conventions, and mlclust.cluster_mesh, on this process's own server."""

import os
import pickle
import subprocess
import sys
import textwrap
import unittest
import warnings

import numpy as np
from sklearn.base import clone
from sklearn.cluster import KMeans as SklearnKMeans
from sklearn.exceptions import NotFittedError
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.utils.estimator_checks import check_estimator

import mlclust
from test_client import face_components, grid

# Every check of sklearn.utils.estimator_checks.check_estimator (scikit-learn 1.2, 33 per
# estimator) runs and passes; these three run but have nothing to test here, and why:
CANNOT_APPLY = {
    "check_clusterer_compute_labels_predict": "no compute_labels parameter: labels_ are "
                                              "always the level's",
    "check_estimators_partial_fit_n_features": "no partial_fit: a job clusters all of X",
    "check_non_transformer_estimators_n_iter": "no max_iter: the server reports no "
                                               "iteration count, so the option is "
                                               "max_iterations, without n_iter_",
}


def blobs():
    """Four blobs of 30 points in 3-d, 10 apart, each row's blob id beside it."""
    rng = np.random.default_rng(7)
    centres = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]], dtype=np.float64)
    x = np.concatenate([c + rng.normal(scale=0.5, size=(30, 3)) for c in centres])
    return x, np.repeat(np.arange(4), 30)


def same_partition(a, b):
    """The two labelings group the rows alike (whatever the cluster numbers)."""
    a, b = np.asarray(a), np.asarray(b)
    pairs = set(zip(a.tolist(), b.tolist()))
    return len(pairs) == len(set(a.tolist())) == len(set(b.tolist()))


ESTIMATORS = [
    mlclust.MultilevelClustering(n_clusters=4),
    mlclust.MultilevelClustering(n_clusters=4, algorithm="pml"),
    mlclust.MultilevelClustering(n_clusters=4, algorithm="hc"),
    mlclust.LocalNeighboursKMeans(n_clusters=4),
    mlclust.KMeans(n_clusters=4),
    mlclust.XMeans(k_min=1, k_max=16),
]


class EstimatorsTest(unittest.TestCase):
    def test_each_finds_the_four_blobs_with_their_centres_and_inertia(self):
        x, blob = blobs()
        for estimator in ESTIMATORS:
            with self.subTest(estimator=repr(estimator)):
                model = clone(estimator).fit(x)
                self.assertTrue(same_partition(model.labels_, blob))
                self.assertEqual(model.labels_.dtype, np.int64)
                self.assertEqual(model.n_clusters_, 4)
                self.assertEqual(model.n_features_in_, 3)
                for k in range(4):
                    rows = x[model.labels_ == k]
                    np.testing.assert_allclose(model.cluster_centers_[k], rows.mean(axis=0),
                                               rtol=0, atol=1e-12)
                want = sum(((x[blob == b] - x[blob == b].mean(axis=0)) ** 2).sum()
                           for b in range(4))
                self.assertAlmostEqual(model.inertia_, want, places=9)
                # predict: the nearest centre; a point at a centre gets that cluster.
                np.testing.assert_array_equal(model.predict(model.cluster_centers_),
                                              np.arange(4))
                np.testing.assert_array_equal(model.predict(x), model.labels_)
                np.testing.assert_array_equal(clone(estimator).fit_predict(x), model.labels_)

    def test_kmeans_equals_scikit_learns_on_separated_blobs(self):
        x, _ = blobs()
        ours = mlclust.KMeans(n_clusters=4, random_state=3).fit(x)
        theirs = SklearnKMeans(n_clusters=4, n_init=1, random_state=3).fit(x)
        self.assertTrue(same_partition(ours.labels_, theirs.labels_))
        self.assertAlmostEqual(ours.inertia_, theirs.inertia_, places=6)

    def test_few_points_get_a_finer_grid(self):
        x, blob = blobs()
        few = x[::10]  # 12 points: the server's grid starts them in fewer than 4 clusters
        model = mlclust.MultilevelClustering(n_clusters=4).fit(few)
        self.assertGreater(model.grid_, 0)
        self.assertGreaterEqual(model.hierarchy_.cluster_counts[0], 4)
        self.assertTrue(same_partition(model.labels_, blob[::10]))
        self.assertEqual(mlclust.MultilevelClustering(n_clusters=4).fit(x).grid_, 0)

    def test_hierarchy_gives_every_level(self):
        x, blob = blobs()
        model = mlclust.MultilevelClustering(n_clusters=1).fit(x)
        self.assertEqual(model.n_clusters_, 1)
        self.assertTrue(same_partition(model.hierarchy_.labels_at(4), blob))
        start = int(model.hierarchy_.cluster_counts[0])
        self.assertEqual(list(model.hierarchy_.cluster_counts), list(range(start, 0, -1)))
        for k in (start, 7, 2):
            self.assertEqual(len(np.unique(model.hierarchy_.labels_at(k))), k)
        with self.assertRaises(mlclust.LevelNotFoundError):
            mlclust.KMeans(n_clusters=3).fit(x).hierarchy_.labels(7)  # one level, K = 3

    def test_auto_k_chooses_the_level(self):
        x, blob = blobs()
        for auto_k in ("bic", "bic-first-decrease"):
            model = mlclust.MultilevelClustering(auto_k=auto_k).fit(x)
            self.assertEqual(model.n_clusters_, 4, auto_k)
            self.assertTrue(same_partition(model.labels_, blob), auto_k)
            done = model.hierarchy_.done
            self.assertEqual(model.n_clusters_, done.bic_best_cluster_count if auto_k == "bic"
                             else done.bic_first_decrease_cluster_count)
            self.assertEqual(model.hierarchy_.cluster_counts[-1], 1)  # every level sent
        with self.assertRaisesRegex(ValueError, "auto_k must be None or one of"):
            mlclust.MultilevelClustering(auto_k="aic").fit(x)

    def test_params_clone_pickle_and_pipeline(self):
        model = mlclust.MultilevelClustering(n_clusters=3, algorithm="pml", grid=4,
                                             options={"pml_until": 10})
        self.assertEqual(model.get_params(), {
            "n_clusters": 3, "algorithm": "pml", "auto_k": None, "grid": 4,
            "optimizer": "lnkmeans", "device": "auto", "random_state": None, "server": None,
            "options": {"pml_until": 10}})
        self.assertIs(model.set_params(n_clusters=4), model)
        self.assertEqual(clone(model).get_params()["n_clusters"], 4)
        x, blob = blobs()
        with self.assertRaises(NotFittedError):
            model.predict(x)
        pipeline = make_pipeline(StandardScaler(), mlclust.MultilevelClustering(n_clusters=4))
        labels = pipeline.fit_predict(x)
        self.assertTrue(same_partition(labels, blob))
        np.testing.assert_array_equal(pipeline.predict(x), labels)
        scaled = StandardScaler().fit_transform(x)
        np.testing.assert_allclose(pipeline[-1].cluster_centers_,
                                   [scaled[labels == k].mean(axis=0) for k in range(4)],
                                   atol=1e-12)
        fitted = mlclust.KMeans(n_clusters=4).fit(x)
        again = pickle.loads(pickle.dumps(fitted))
        np.testing.assert_array_equal(again.predict(x), fitted.labels_)
        np.testing.assert_array_equal(again.hierarchy_.labels_at(4), fitted.labels_)

    def test_bad_parameters_and_input_are_refused_clearly(self):
        x, _ = blobs()
        cases = [
            (mlclust.MultilevelClustering(algorithm="kmeans"), x, ValueError,
             "algorithm must be ml, pml or hc, got 'kmeans'"),
            (mlclust.KMeans(n_clusters=121), x, ValueError,
             "n_samples=120 should be >= n_clusters=121"),
            (mlclust.KMeans(n_clusters=2.5), x, TypeError, "n_clusters must be an integer"),
            (mlclust.KMeans(device="tpu"), x, ValueError, "device must be auto, gpu or cpu"),
            (mlclust.MultilevelClustering(n_clusters=100, grid=2), x, ValueError,
             r"n_clusters=100 is more than the \d+ clusters of the voxel-grid start \(grid=2\)"),
            (mlclust.KMeans(n_clusters=2), np.array([[0.0, np.nan], [1.0, 1.0]]), ValueError,
             "NaN"),
            (mlclust.KMeans(n_clusters=2, options={"max_iterations": 0}), x, mlclust.Error,
             "max-iterations"),
        ]
        for model, data, kind, message in cases:
            with self.subTest(model=repr(model)), self.assertRaisesRegex(kind, message):
                model.fit(data)
        fitted = mlclust.KMeans(n_clusters=4).fit(x)
        with self.assertRaisesRegex(ValueError, "X has 2 features, but KMeans is expecting 3"):
            fitted.predict(x[:, :2])

    def test_scikit_learns_estimator_checks(self):
        ran = set()
        for estimator in ESTIMATORS:
            for instance, check in check_estimator(clone(estimator), generate_only=True):
                name = getattr(check, "func", check).__name__
                with self.subTest(estimator=repr(estimator), check=name):
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        check(instance)  # a SkipTest would fail the test too
                ran.add(name)
        for name in ("check_clustering", "check_fit_idempotent", "check_estimators_pickle",
                     "check_pipeline_consistency", *CANNOT_APPLY):
            self.assertIn(name, ran)
        self.assertGreaterEqual(len(ran), 31)


class ClusterMeshTest(unittest.TestCase):
    def test_arrays_as_trimesh_and_pyvista_hold_them(self):
        vertices, faces = grid(6)  # 72 triangles
        h = mlclust.cluster_mesh(vertices.astype(np.float64), faces.astype(np.int64),
                                 algorithm="ml", energy="cvd")
        self.assertEqual(h.num_elements, 72)
        self.assertEqual(h.cluster_counts[0], 72)
        self.assertEqual(face_components(faces, h.labels(6)), 6)
        self.assertIsNone(h.polygons)
        # pyvista's flat cell array of the same triangles: the same hierarchy.
        flat = np.hstack([np.full((len(faces), 1), 3), faces]).ravel()
        same = mlclust.cluster_mesh(vertices, flat)
        self.assertEqual(list(same.cluster_counts), list(h.cluster_counts))
        np.testing.assert_array_equal(same.labels(6), h.labels(6))
        # Quads (two triangles each): split in fans, no level splits a quad.
        quads = faces.reshape(-1, 2, 3)  # triangles (a, b, c), (c, b, d) of each square
        cells = np.hstack([np.full((len(quads), 1), 4), quads[:, 0, :2], quads[:, 1, 2:3],
                           quads[:, 0, 2:3]]).ravel()  # a, b, d, c: the square's corners
        q = mlclust.cluster_mesh(vertices, cells, n_clusters=5)
        np.testing.assert_array_equal(q.polygons, np.full(36, 2))
        self.assertEqual(q.cluster_counts[0], 36)
        labels = q.labels(5)
        np.testing.assert_array_equal(labels[0::2], labels[1::2])
        self.assertEqual(len(mlclust.labels_per_polygon(labels, q.polygons)), 36)
        with self.assertRaisesRegex(ValueError, "cell at offset 4 has 4 corners but only 2 follow"):
            mlclust.cluster_mesh(vertices, [3, 0, 1, 2, 4, 0, 1])


class WithoutScikitLearnTest(unittest.TestCase):
    def test_the_same_methods_without_sklearn(self):
        script = textwrap.dedent("""
            import sys
            sys.modules["sklearn"] = None  # import sklearn raises ImportError
            import numpy as np
            import mlclust
            from mlclust import estimators
            assert not estimators.HAVE_SKLEARN
            x = np.array([[0, 0], [0, 1], [10, 0], [10, 1]], dtype=float)
            model = mlclust.KMeans(n_clusters=2, random_state=5)
            assert model.get_params()["random_state"] == 5, model.get_params()
            assert model.set_params(n_clusters=2) is model
            try:
                model.predict(x)
                raise AssertionError("predict before fit")
            except estimators.NotFittedError:
                pass
            print(model.fit_predict(x).tolist(), model.predict([[9, 9]]).tolist())
            for bad, kind in (([[0, np.inf]], ValueError), (x[0], ValueError)):
                try:
                    model.fit(bad)
                    raise AssertionError(f"fit({bad!r})")
                except kind as e:
                    print(type(e).__name__, e)
            try:
                model.set_params(clusters=3)
            except ValueError as e:
                print(e)
            print(repr(model))
        """)
        result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                                timeout=120)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertEqual(result.stdout.splitlines(), [
            "[0, 0, 1, 1] [1]",
            "ValueError Input contains NaN or infinity",
            "ValueError Expected 2D array, got 1D array instead: reshape your data "
            "(X.reshape(-1, 1) for a single feature)",
            "invalid parameter 'clusters' for KMeans; valid parameters: ['device', 'init', "
            "'max_iterations', 'n_clusters', 'options', 'random_state', 'server']",
            "KMeans(device='auto', init='kmeans++', max_iterations=300, n_clusters=2, "
            "options=None, random_state=5, server=None)"])


if __name__ == "__main__":
    unittest.main()
