"""mlclust: multilevel clustering of meshes and point sets over gRPC.

    import mlclust
    vertices, faces = mlclust.read_mesh("bunny.obj")
    with mlclust.Client("localhost:50051") as client:
        h = client.cluster_mesh(vertices, faces, algo="ml", energy="cvd")
        labels = h.labels(100)         # one cluster id 0..99 per face
        print(h.energy(100), len(h.levels))
    mlclust.write_clustered("bunny-100.ply", vertices, faces, labels)

See Client.cluster_mesh, Client.cluster_points and Hierarchy; read_meshlets reads the file of
`mlclust mesh INPUT --meshlets FILE`.
"""

from .client import ALGORITHMS, ENERGIES, Client, Error, Progress
from .hierarchy import Hierarchy, Level, compact_labels, labels_per_polygon
from .meshio import read_mesh, write_clustered
from .meshlets import Meshlets, read_meshlets

__all__ = ["ALGORITHMS", "ENERGIES", "Client", "Error", "Hierarchy", "Level", "Meshlets",
           "Progress", "compact_labels", "labels_per_polygon", "read_mesh", "read_meshlets",
           "write_clustered"]
