"""Plates grouped into small spatial clusters with a bounding sphere each, which the gather
kernels skip whole when the sphere lies above the sand (`gather`). Plain numpy."""
import numpy as np


def cluster_plates(centroids, size=32):
    """Order plates into spatial clusters of at most `size` by recursive halving along the
    widest axis. Returns (order, cluster_start): plates order[cluster_start[c]:
    cluster_start[c+1]] form cluster c."""
    order, starts = [], [0]
    pending = [np.arange(len(centroids))]
    while pending:
        group = pending.pop()
        if len(group) <= size:
            order.extend(group)
            starts.append(len(order))
            continue
        points = centroids[group]
        axis = np.argmax(np.ptp(points, axis=0))
        ranked = group[np.argsort(points[:, axis], kind='stable')]
        half = len(ranked) // 2
        pending.extend([ranked[half:], ranked[:half]])
    return np.array(order, dtype=np.int64), np.array(starts, dtype=np.int64)
