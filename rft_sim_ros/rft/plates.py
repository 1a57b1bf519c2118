"""Plates: the surface elements RFT integrates over.

A `Plates` set holds, for each plate, its centroid (m), outward unit normal and area (m^2),
all in one frame (usually the frame of the body that carries them). Plates come from the
triangles of a surface mesh, refined so that no edge is longer than a target length; that
gives plates of even size without hand remeshing.
"""
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Plates:
    """centroids (N, 3) m, normals (N, 3) outward unit vectors, areas (N,) m^2, one frame."""
    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray

    def __post_init__(self):
        n = len(self.areas)
        if self.centroids.shape != (n, 3) or self.normals.shape != (n, 3):
            raise ValueError('plates need (N, 3) centroids and normals and (N,) areas')

    def __len__(self):
        return len(self.areas)

    @property
    def total_area(self):
        """Sum of plate areas, m^2."""
        return float(self.areas.sum())

    @classmethod
    def from_mesh(cls, mesh):
        """One plate per triangle of `mesh` (a trimesh.Trimesh), in the mesh's frame."""
        return cls.from_triangles(np.asarray(mesh.triangles, dtype=float))

    @classmethod
    def from_triangles(cls, triangles):
        """One plate per triangle ((T, 3, 3) vertices, m, counter-clockwise seen from
        outside). Degenerate (zero-area) triangles are dropped."""
        cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        double_area = np.linalg.norm(cross, axis=1)
        keep = double_area > 0.0
        return cls(centroids=triangles[keep].mean(axis=1),
                   normals=cross[keep] / double_area[keep, None],
                   areas=0.5 * double_area[keep])

    def subset(self, keep):
        """The plates selected by boolean mask or index array `keep`."""
        return Plates(self.centroids[keep], self.normals[keep], self.areas[keep])

    @staticmethod
    def concatenate(parts):
        """One Plates set from several in the same frame."""
        parts = list(parts)
        if not parts:
            return Plates(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
        return Plates(np.concatenate([p.centroids for p in parts]),
                      np.concatenate([p.normals for p in parts]),
                      np.concatenate([p.areas for p in parts]))


def bisect(triangles):
    """Each triangle ((T, 3, 3)) cut in two at the midpoint of its longest edge: (2T, 3, 3),
    same orientation, same plane, so the surface they cover is unchanged."""
    edges = np.stack([triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 1],
                      triangles[:, 0] - triangles[:, 2]], axis=1)
    longest = np.argmax(np.linalg.norm(edges, axis=2), axis=1)
    # rotate each triangle so that its longest edge runs from vertex 0 to vertex 1
    order = (np.arange(3)[None, :] + longest[:, None]) % 3
    triangles = np.take_along_axis(triangles, order[:, :, None], axis=1)
    middle = 0.5 * (triangles[:, 0] + triangles[:, 1])
    return np.concatenate([np.stack([triangles[:, 0], middle, triangles[:, 2]], axis=1),
                           np.stack([middle, triangles[:, 1], triangles[:, 2]], axis=1)])


def longest_edges(triangles):
    """(T,) length of each triangle's longest edge, m."""
    edges = np.stack([triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 1],
                      triangles[:, 0] - triangles[:, 2]], axis=1)
    return np.linalg.norm(edges, axis=2).max(axis=1)


def refine(mesh, max_edge):
    """Triangles of `mesh` (a trimesh.Trimesh, m) split until no edge exceeds max_edge (m).

    Each triangle is bisected at the midpoint of its longest edge, repeatedly. Unlike
    4-way midpoint subdivision this turns long slivers (common in CAD meshes and cone
    sides) into well-shaped triangles, so plates have even size and shape. Plates need not
    form a conforming mesh, so triangles are split independently. Returns a new Trimesh
    (unmerged vertices, three per triangle).
    """
    import trimesh  # (here: ~0.5 s to import, and runs with cached plates never need it)
    triangles = np.asarray(mesh.triangles, dtype=float)
    done = []
    while len(triangles):
        split = longest_edges(triangles) > max_edge
        done.append(triangles[~split])
        triangles = bisect(triangles[split])
    triangles = np.concatenate(done) if done else np.zeros((0, 3, 3))
    return trimesh.Trimesh(vertices=triangles.reshape(-1, 3),
                           faces=np.arange(3 * len(triangles)).reshape(-1, 3), process=False)


def top_up(triangles, count):
    """Bisect the largest triangles until there are exactly `count` (>= len(triangles)):
    plates of even size, the surface unchanged."""
    while len(triangles) < count:
        doubled = 0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0],
                                                triangles[:, 2] - triangles[:, 0]), axis=1)
        largest = np.argsort(-doubled, kind='stable')[:count - len(triangles)]
        keep = np.ones(len(triangles), dtype=bool)
        keep[largest] = False
        triangles = np.concatenate([triangles[keep], bisect(triangles[largest])])
    return triangles


def edge_for_plate_area(area):
    """Edge length (m) of an equilateral triangle of the given area (m^2)."""
    return float(np.sqrt(4.0 * area / np.sqrt(3.0)))
