"""Clustering estimators in scikit-learn's conventions, over the mlclust service.

    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    import mlclust
    model = make_pipeline(StandardScaler(), mlclust.MultilevelClustering(n_clusters=5))
    labels = model.fit_predict(X)                 # X: (n_samples, n_features)
    ml = model[-1]
    ml.cluster_centers_, ml.inertia_, ml.predict(X[:10])
    ml.hierarchy_.labels_at(12)                   # any other level, nothing recomputed

Every estimator runs one job per fit on the server given by `server` (None: one server of
this process's own, started at the first fit and stopped at exit; mlclust.Client()).
fit(X) sets labels_ (0..n_clusters_-1, int64), cluster_centers_ (the mean of each
cluster's rows of X, float64), inertia_ (the sum of squared distances of the rows to their
cluster's centre), n_clusters_, n_features_in_ and hierarchy_ (mlclust.Hierarchy: every
level the job sent). predict(X) gives the nearest centre. The job's input is X as float32.

With scikit-learn importable (python3-sklearn) the estimators are
sklearn.base.BaseEstimator and ClusterMixin subclasses, so get_params / set_params /
clone / Pipeline / GridSearchCV work as for scikit-learn's own; without it they keep the
same methods. They pass sklearn.utils.estimator_checks.check_estimator
(python/tests/test_estimators.py lists the checks that cannot apply).
"""

import inspect
import threading

import numpy as np

from .client import Client
from .hierarchy import Hierarchy

try:
    from sklearn.base import BaseEstimator as _BaseEstimator
    from sklearn.base import ClusterMixin as _ClusterMixin
    from sklearn.utils.validation import check_is_fitted as _check_is_fitted
    HAVE_SKLEARN = True
except ImportError:  # the same methods without scikit-learn
    HAVE_SKLEARN = False

    class NotFittedError(ValueError, AttributeError):
        """An estimator used before fit (as sklearn.exceptions.NotFittedError)."""

    class _BaseEstimator:
        """get_params / set_params from __init__'s keyword parameters (as scikit-learn's)."""

        @classmethod
        def _get_param_names(cls):
            parameters = inspect.signature(cls.__init__).parameters.values()
            return sorted(p.name for p in parameters if p.name != "self"
                          and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD))

        def get_params(self, deep=True):
            return {name: getattr(self, name) for name in self._get_param_names()}

        def set_params(self, **params):
            valid = self._get_param_names()
            for name, value in params.items():
                if name not in valid:
                    raise ValueError(f"invalid parameter {name!r} for {type(self).__name__}; "
                                     f"valid parameters: {valid}")
                setattr(self, name, value)
            return self

        def __repr__(self):
            args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
            return f"{type(self).__name__}({args})"

    class _ClusterMixin:
        _estimator_type = "clusterer"

        def fit_predict(self, X, y=None):
            self.fit(X)
            return self.labels_

    def _check_is_fitted(estimator):
        if not hasattr(estimator, "cluster_centers_"):
            raise NotFittedError(f"this {type(estimator).__name__} is not fitted yet; call "
                                 "fit first")

_CLIENTS = {}
_CLIENTS_LOCK = threading.Lock()


def shared_client(server=None):
    """The Client the estimators and cluster_mesh use for `server` (None: this process's
    own server), made at the first call and kept for the next."""
    with _CLIENTS_LOCK:
        client = _CLIENTS.get(server)
        if client is None:
            client = Client(server)
            _CLIENTS[server] = client
        return client


def _validate(estimator, X, reset):
    """X as a finite 2-d float array; records (reset) or checks n_features_in_."""
    if HAVE_SKLEARN:
        return estimator._validate_data(X, reset=reset, dtype=[np.float64, np.float32],
                                        ensure_min_samples=1)
    if hasattr(X, "toarray") or hasattr(X, "tocsr"):
        raise TypeError("sparse input is not supported: pass a dense array (X.toarray())")
    X = np.asarray(X)
    if X.dtype.kind not in "fiub":
        X = X.astype(np.float64)
    elif X.dtype != np.float32:
        X = X.astype(np.float64)
    if X.ndim != 2:
        raise ValueError(f"Expected 2D array, got {X.ndim}D array instead: reshape your data "
                         "(X.reshape(-1, 1) for a single feature)")
    if X.shape[0] == 0 or X.shape[1] == 0:
        raise ValueError(f"Found array with {X.shape[0]} sample(s) and {X.shape[1]} "
                         "feature(s); at least one of each is required")
    if not np.all(np.isfinite(X)):
        raise ValueError("Input contains NaN or infinity")
    if reset:
        estimator.n_features_in_ = X.shape[1]
    elif X.shape[1] != estimator.n_features_in_:
        raise ValueError(f"X has {X.shape[1]} features, but {type(estimator).__name__} is "
                         f"expecting {estimator.n_features_in_} features as input")
    return X


def _nearest_centre(X, centres):
    """The index of the nearest centre of each row (squared Euclidean), in blocks."""
    X = np.asarray(X, dtype=np.float64)
    out = np.empty(X.shape[0], dtype=np.int64)
    c2 = np.einsum("ij,ij->i", centres, centres)
    step = max(1, (1 << 22) // max(1, centres.shape[0]))
    for start in range(0, X.shape[0], step):
        block = X[start:start + step]
        distances = c2[None, :] - 2.0 * block @ centres.T
        out[start:start + step] = np.argmin(distances, axis=1)
    return out


def _centres(X, labels, k):
    """The mean of each cluster's rows (one bincount per column: far faster than add.at)."""
    X = np.asarray(X, dtype=np.float64)
    counts = np.bincount(labels, minlength=k).astype(np.float64)
    sums = np.stack([np.bincount(labels, weights=X[:, j], minlength=k)
                     for j in range(X.shape[1])], axis=1)
    return sums / counts[:, None]


class _PointClustering(_ClusterMixin, _BaseEstimator):
    """What the point estimators share: one job per fit, the chosen level's labels."""

    _algorithm = None  # the service's algorithm name ("kmeans", ...)

    def _job(self):
        """(algorithm, clusters sent, options) of the job."""
        raise NotImplementedError

    def _level(self, hierarchy):
        """The number of clusters of the level that labels_ comes from."""
        raise NotImplementedError

    def _check_clusters(self, name, value, n_samples, low=1):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an integer, got {value!r}")
        if value < low:
            raise ValueError(f"{name}={value} must be at least {low}")
        if value > n_samples:
            raise ValueError(f"n_samples={n_samples} should be >= {name}={value}")

    def fit(self, X, y=None):
        """Clusters the rows of X (y is ignored); returns self."""
        X = _validate(self, X, reset=True)
        algorithm, clusters, options = self._job(X.shape[0])
        if self.device not in ("auto", "gpu", "cpu"):
            raise ValueError(f"device must be auto, gpu or cpu, got {self.device!r}")
        seed = 1 if self.random_state is None else self.random_state
        if isinstance(seed, np.random.RandomState):
            seed = int(seed.randint(1 << 31))
        options = {**options, **(self.options or {})}
        hierarchy = self._run(X, algorithm, clusters, int(seed), options)
        k = self._level(hierarchy)
        labels = hierarchy.labels(k).astype(np.int64)
        self.hierarchy_ = hierarchy
        self.labels_ = labels
        self.n_clusters_ = int(labels.max()) + 1
        self.cluster_centers_ = _centres(X, labels, self.n_clusters_)
        residual = np.asarray(X, dtype=np.float64) - self.cluster_centers_[labels]
        self.inertia_ = float(np.einsum("ij,ij->", residual, residual))
        return self

    def _run(self, X, algorithm, clusters, seed, options):
        return shared_client(self.server).cluster_points(
            X, algo=algorithm, clusters=clusters, seed=seed, device=self.device, **options)

    def predict(self, X):
        """The nearest cluster centre (cluster_centers_) of each row of X."""
        _check_is_fitted(self)
        X = _validate(self, X, reset=False)
        return _nearest_centre(X, self.cluster_centers_)

    def _more_tags(self):
        return {"non_deterministic": False, "X_types": ["2darray"]}


class MultilevelClustering(_PointClustering):
    """The multilevel clustering of points: every level from the voxel-grid start (section
    6.2) down to n_clusters (or, with auto_k, down to one), each a merge of two clusters
    (ML, section 6.3; HC, Alg. 2.6) or of every mutual optimal pair (PML, Alg. 5.3),
    followed by LN k-means (Alg. 6.1) where optimizer="lnkmeans".

    n_clusters: the level labels_ takes (ignored with auto_k). auto_k: None, "bic" (the
    level of highest BIC, section 6.6), "bic-first-decrease" (the level where the BIC read
    from few clusters to many first decreases, X-means' rule) or "elbow" (the first bend
    of the energy curve, section 4.4). grid: voxels per dimension of the start (0: about
    eight points per occupied cell, and where that start has fewer than n_clusters
    clusters, as on a few dozen points, the job again with 2, 4, 8, ... voxels per
    dimension until it has enough: the first grid that does is grid_). An explicit grid
    whose start has fewer than n_clusters clusters is refused.
    device: auto, gpu or cpu. random_state: the job's seed (None: 1). server: an address,
    or None for this process's own server. options: further algorithm options by name
    ({"bounded_drift": 0.03, "pml_until": 100, ...}; {"preset": "dissertation"}: the
    text's variants of the defaults that are ours, with grid >= 1; the estimators' own
    parameters, init, grid and optimizer, are sent as given and win over the preset).
    """

    _AUTO_K = ("bic", "bic-first-decrease", "elbow")

    def __init__(self, n_clusters=8, *, algorithm="ml", auto_k=None, grid=0,
                 optimizer="lnkmeans", device="auto", random_state=None, server=None,
                 options=None):
        self.n_clusters = n_clusters
        self.algorithm = algorithm
        self.auto_k = auto_k
        self.grid = grid
        self.optimizer = optimizer
        self.device = device
        self.random_state = random_state
        self.server = server
        self.options = options

    def _job(self, n_samples):
        if self.algorithm not in ("ml", "pml", "hc"):
            raise ValueError(f"algorithm must be ml, pml or hc, got {self.algorithm!r}")
        if self.auto_k is not None and self.auto_k not in self._AUTO_K:
            raise ValueError(f"auto_k must be None or one of {list(self._AUTO_K)}, got "
                             f"{self.auto_k!r}")
        options = {"grid": int(self.grid)}
        if self.algorithm != "hc":
            options["optimizer"] = self.optimizer
        if self.auto_k is not None:
            return self.algorithm, 1, options
        self._check_clusters("n_clusters", self.n_clusters, n_samples)
        return self.algorithm, int(self.n_clusters), options

    def _run(self, X, algorithm, clusters, seed, options):
        hierarchy = super()._run(X, algorithm, clusters, seed, options)
        self.grid_ = int(self.grid)
        if self.auto_k is not None or self.grid != 0:
            return hierarchy
        # The server's grid aims at about eight points per cell: on few points a start of
        # fewer clusters than asked. Finer grids until the start has enough (at most
        # 2^20 voxels per dimension, the option's limit).
        grid = 2
        while int(hierarchy.cluster_counts[0]) < clusters and grid <= 1 << 20:
            hierarchy = super()._run(X, algorithm, clusters, seed, {**options, "grid": grid})
            self.grid_ = grid
            grid *= 2
        return hierarchy

    def _level(self, hierarchy):
        done = hierarchy.done
        if self.auto_k is None:
            k = int(self.n_clusters)
            start = int(hierarchy.cluster_counts[0])
            if start < k:
                raise ValueError(
                    f"n_clusters={k} is more than the {start} clusters of the voxel-grid "
                    f"start (grid={self.grid_}); give a finer grid or fewer clusters")
            return k
        if self.auto_k == "elbow":
            if not len(done.elbow_cluster_counts):
                raise ValueError("auto_k='elbow': the energy curve has no bend; try "
                                 "auto_k='bic'")
            return int(done.elbow_cluster_counts[0])
        k = int(done.bic_best_cluster_count if self.auto_k == "bic"
                else done.bic_first_decrease_cluster_count)
        if k == 0:
            raise ValueError(f"auto_k={self.auto_k!r}: the server computed no BIC")
        return k


class LocalNeighboursKMeans(_PointClustering):
    """LN k-means (Alg. 6.1): every cluster keeps 2d local neighbours, one per half-axis
    subspace (eq. 6.1), and a point is checked against at most 4d - 1 clusters.

    init: "kmeans++", "random" or "grid" (one cluster per occupied voxel, section 6.2;
    n_clusters is then ignored). max_iterations: LN k-means rounds at most (the server
    reports no count, so there is no n_iter_). Other parameters as MultilevelClustering.
    """

    _algorithm = "lnkmeans"

    def __init__(self, n_clusters=8, *, init="kmeans++", max_iterations=300, device="auto",
                 random_state=None, server=None, options=None):
        self.n_clusters = n_clusters
        self.init = init
        self.max_iterations = max_iterations
        self.device = device
        self.random_state = random_state
        self.server = server
        self.options = options

    def _job(self, n_samples):
        if self.init != "grid":
            self._check_clusters("n_clusters", self.n_clusters, n_samples)
        return self._algorithm, int(self.n_clusters), {
            "init": self.init, "max_iterations": int(self.max_iterations)}

    def _level(self, hierarchy):
        # The result follows the seeding level (at the same count, or the grid's).
        return int(hierarchy.cluster_counts[-1])


class KMeans(LocalNeighboursKMeans):
    """Brute-force Lloyd iterations (Alg. 2.4) from k-means++ or random centres: the
    baseline. Parameters as LocalNeighboursKMeans (init "kmeans++" or "random")."""

    _algorithm = "kmeans"


class XMeans(_PointClustering):
    """X-means (Alg. 2.5, Pelleg & Moore): k-means from k_min clusters, then every cluster
    split in two by 2-means where the BIC of the halves beats the cluster's, until no split
    is kept or k_max; labels_ is the round of largest BIC, n_clusters_ the K it found.

    k_max: 0 = the number of points. split_trials: 2-means runs per virtual split.
    Other parameters as LocalNeighboursKMeans.
    """

    def __init__(self, k_min=1, k_max=0, *, split_trials=1, init="kmeans++",
                 max_iterations=300, device="auto", random_state=None, server=None,
                 options=None):
        self.k_min = k_min
        self.k_max = k_max
        self.split_trials = split_trials
        self.init = init
        self.max_iterations = max_iterations
        self.device = device
        self.random_state = random_state
        self.server = server
        self.options = options

    def _job(self, n_samples):
        self._check_clusters("k_min", self.k_min, n_samples)
        # No round can have more clusters than points: a k_max above is that many.
        return "xmeans", int(self.k_min), {
            "kmax": min(int(self.k_max), n_samples), "split_trials": int(self.split_trials),
            "init": self.init, "max_iterations": int(self.max_iterations)}

    def _level(self, hierarchy):
        return int(hierarchy.cluster_counts[-1])


def cluster_mesh(vertices, faces, n_clusters=0, *, algorithm="ml", energy="cvd",
                 device="auto", server=None, **options) -> Hierarchy:
    """Clusters a triangle mesh on this process's own server (or `server`) and returns the
    hierarchy: Client.cluster_mesh(vertices, faces, algorithm, energy, n_clusters, ...).

    vertices (V, 3) and faces (F, 3) as trimesh holds them (mesh.vertices, mesh.faces), or
    a pyvista PolyData's points and its flat cell array ([3, a, b, c, 3, ...]; polygons of
    more corners are split in fans, and the returned hierarchy's `polygons` holds each
    cell's triangle count: labels_per_polygon(h.labels(k), h.polygons) is one label per
    cell, and no level splits a cell). Options as for Client.cluster_mesh.
    """
    faces = np.asarray(faces)
    polygons = options.pop("polygons", None)
    if faces.ndim == 1:
        if polygons is not None:
            raise ValueError("polygons= is for (F, 3) faces; a flat cell array gives them")
        faces, polygons = _triangulate_cells(faces)
    hierarchy = shared_client(server).cluster_mesh(
        vertices, faces, algo=algorithm, energy=energy, clusters=n_clusters, device=device,
        polygons=polygons, **options)
    hierarchy.polygons = None if polygons is None else np.asarray(polygons, dtype=np.int64)
    return hierarchy


def _triangulate_cells(cells):
    """(faces (F, 3), triangles per cell, or None where every cell is a triangle) of a VTK
    cell array [n, i_1..i_n, n, ...]; a cell of n >= 3 corners becomes n - 2 triangles
    (i_1, i_k, i_k+1)."""
    cells = np.asarray(cells, dtype=np.int64)
    triangles, counts = [], []
    at = 0
    while at < cells.size:
        n = int(cells[at])
        if n < 3 or at + 1 + n > cells.size:
            raise ValueError(f"the cell array's cell at offset {at} has {n} corners"
                             + ("" if n < 3 else f" but only {cells.size - at - 1} follow"))
        corners = cells[at + 1:at + 1 + n]
        for k in range(1, n - 1):
            triangles.append((corners[0], corners[k], corners[k + 1]))
        counts.append(n - 2)
        at += 1 + n
    faces = np.array(triangles, dtype=np.int64).reshape(-1, 3)
    return faces, (None if all(c == 1 for c in counts) else np.array(counts, dtype=np.int64))
