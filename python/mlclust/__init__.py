"""mlclust: multilevel clustering of meshes and point sets over gRPC.

    import mlclust
    with mlclust.Client("localhost:50051") as client:
        h = client.cluster_mesh(vertices, faces, algo="ml", energy="cvd")
        labels = h.labels(100)         # one cluster id 0..99 per face
        print(h.energy(100), len(h.levels))

See Client.cluster_mesh, Client.cluster_points and Hierarchy.
"""

from .client import ALGORITHMS, ENERGIES, Client, Error, Progress
from .hierarchy import Hierarchy, Level, compact_labels

__all__ = ["ALGORITHMS", "ENERGIES", "Client", "Error", "Hierarchy", "Level", "Progress",
           "compact_labels"]
