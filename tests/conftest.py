"""Shared fixtures: Taichi in debug mode (bounds checks), f64 unless a test asks for f32."""

import numpy as np
import pytest

import taichi_dcd


@pytest.fixture
def f64():
    taichi_dcd.init(arch="cpu", precision="f64", debug=True)


@pytest.fixture
def f32():
    taichi_dcd.init(arch="cpu", precision="f32", debug=True)


def random_pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n random triangle pairs with vertices uniform in the unit cube (~28% intersect)."""
    rng = np.random.default_rng(seed)
    return rng.random((n, 3, 3)), rng.random((n, 3, 3))


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random proper rotation matrix (3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q
