"""Numpy reference for ``ptam.edgelet.edge_sample_kernels.sobel_at``: the 3×3 Sobel gradient at pixels."""

import numpy as np


def sobel_at_ref(image: np.ndarray, xy: np.ndarray) -> np.ndarray:
    ix = np.clip(np.round(xy[:, 0]).astype(int), 1, image.shape[1] - 2)
    iy = np.clip(np.round(xy[:, 1]).astype(int), 1, image.shape[0] - 2)

    def at(dy: int, dx: int) -> np.ndarray:
        return image[iy + dy, ix + dx].astype(np.float64)

    gx = at(-1, 1) + 2.0 * at(0, 1) + at(1, 1) - at(-1, -1) - 2.0 * at(0, -1) - at(1, -1)
    gy = at(1, -1) + 2.0 * at(1, 0) + at(1, 1) - at(-1, -1) - 2.0 * at(-1, 0) - at(-1, 1)
    return np.stack([gx, gy], axis=-1)
