"""Shared fixtures: the workspace's built-in fixtures, the shared data (skipped, or failing under
NLOS_REQUIRE_DATA=1, when absent), scratch directories."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

WORKSPACE = Path(__file__).resolve().parents[3]
FIXTURES = WORKSPACE / "fixtures" / "builtin"
SHARED = Path(os.environ.get("NLOS_SHARED_DATA", WORKSPACE.parent / "shared" / "data"))


def require_data() -> bool:
    return os.environ.get("NLOS_REQUIRE_DATA", "") not in ("", "0")


def shared(rel: str) -> Path:
    """A shared data file, or a skip (a failure with NLOS_REQUIRE_DATA=1) when it is absent."""
    path = SHARED / rel
    if not path.exists():
        if require_data():
            pytest.fail(f"{path} is absent and NLOS_REQUIRE_DATA is set")
        pytest.skip(f"{path} is absent (shared data not beside the checkout)")
    return path


@pytest.fixture
def builtin_capture() -> Path:
    return FIXTURES / "capture.hdf5"


@pytest.fixture
def builtin_truth() -> Path:
    return FIXTURES / "truth.obj"


def random_triangles(seed: int = 1):
    """Four small triangles around z = 0.4 m facing the wall (as the renderer's own gradient test)."""
    rng = np.random.default_rng(seed)
    points, faces = [], []
    for t in range(4):
        c = np.array([rng.random() * 0.3 - 0.15, rng.random() * 0.3 - 0.15, 0.35 + 0.1 * rng.random()])
        a = c + np.array([0.05 + 0.03 * rng.random(), 0.02 * rng.random(), 0.03 * (rng.random() - 0.5)])
        b = c + np.array([0.02 * rng.random(), 0.05 + 0.03 * rng.random(), 0.03 * (rng.random() - 0.5)])
        points += [c, b, a]
        faces.append([3 * t, 3 * t + 1, 3 * t + 2])
    return np.array(points, dtype=np.float32), np.array(faces, dtype=np.int64)
