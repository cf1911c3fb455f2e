"""Hand-built single observations for the policy masks' cell-by-cell tests."""

import numpy as np


def hand_observation(
    h=5, w=5, cell=(2, 2), budget=30, targets=(), nfz=(), covered=(), landing=()
) -> dict[str, np.ndarray]:
    """A batch of one observation on an h×w map: the given landing, target and no-fly cells,
    the UAV at ``cell`` with ``budget`` left and the ``covered`` cells seen."""
    layers = np.zeros((3, h, w), dtype=np.float32)  # landing, target, nfz
    for channel, cells in enumerate((landing, targets, nfz)):
        for r, c in cells:
            layers[channel, r, c] = 1
    coverage = np.zeros((1, h, w), dtype=np.int8)
    for r, c in covered:
        coverage[0, r, c] = 1
    position = np.zeros((1, h, w), dtype=np.int8)
    position[0, cell[0], cell[1]] = 1
    budget = np.array([[budget]], dtype=np.float32)
    return {"map": layers, "coverage": coverage, "position": position, "budget": budget}
