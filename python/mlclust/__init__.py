"""mlclust: multilevel clustering of meshes and point sets, in-process or over gRPC.

    import mlclust
    vertices, faces = mlclust.read_mesh("bunny.obj")
    h = mlclust.cluster_mesh(vertices, faces, algorithm="ml", energy="cvd")
    labels = h.labels(100)             # one cluster id 0..99 per face
    print(h.energy(100), len(h.levels))
    mlclust.write_clustered("bunny-100.ply", vertices, faces, labels)

    model = mlclust.MultilevelClustering(n_clusters=5).fit(X)   # scikit-learn's conventions
    model.labels_, model.cluster_centers_, model.hierarchy_.labels_at(12)

With no address, Client() runs the bundled server for the caller (a private Unix socket,
stopped with the client); Client("host:port") talks to a remote one. Install with
`python3 -m pip install --no-build-isolation --no-index ./python` (python/README.md).
See Client.cluster_mesh, Client.cluster_points, Hierarchy and the estimators; read_meshlets
reads the file of `mlclust mesh INPUT --meshlets FILE`.
"""

from ._version import __version__
from .client import ALGORITHMS, ENERGIES, Client, Error, Progress
from .estimators import (KMeans, LocalNeighboursKMeans, MultilevelClustering, XMeans,
                         cluster_mesh, shared_client)
from .hierarchy import Hierarchy, Level, LevelNotFoundError, compact_labels, labels_per_polygon
from .meshio import read_mesh, write_clustered
from .meshlets import Meshlets, read_meshlets

__all__ = ["ALGORITHMS", "ENERGIES", "Client", "Error", "Hierarchy", "KMeans", "Level",
           "LevelNotFoundError", "LocalNeighboursKMeans", "Meshlets", "MultilevelClustering",
           "Progress", "XMeans", "__version__", "cluster_mesh", "compact_labels",
           "labels_per_polygon", "read_mesh", "read_meshlets", "shared_client",
           "write_clustered"]
