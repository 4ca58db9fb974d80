import numpy as np
import pytest
from scipy.spatial import cKDTree


def worst_overlap(positions, radii):
    """Worst (r_i + r_j - d) / ((r_i + r_j)/2) over all pairs (a test oracle, brute force for small N)."""
    positions = np.asarray(positions)
    pairs = cKDTree(positions).query_pairs(2 * radii.max(), output_type="ndarray")
    if not len(pairs):
        return 0.0
    i, j = pairs.T
    d = np.linalg.norm(positions[i] - positions[j], axis=1)
    rsum = radii[i] + radii[j]
    return max(0.0, float(((rsum - d) / (rsum / 2)).max()))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
