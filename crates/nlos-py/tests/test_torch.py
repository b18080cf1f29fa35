"""The PyTorch layer: its backward is the renderer's adjoint (checked against finite differences), the
example fit lowers its loss, and its visibility follows the vertices. Skipped where torch is not installed,
unless NLOS_REQUIRE_TORCH=1 (CI, which installs Debian's CPU build of PyTorch)."""

from __future__ import annotations

import os
import runpy
from pathlib import Path

import numpy as np
import pytest

try:
    import torch
except ImportError:
    if os.environ.get("NLOS_REQUIRE_TORCH", "") not in ("", "0"):
        raise
    pytest.skip("torch is not installed", allow_module_level=True)

import nlos  # noqa: E402
import nlos.torch  # noqa: E402
from conftest import WORKSPACE, random_triangles, shared  # noqa: E402


def test_backward_matches_finite_differences():
    v, f = random_triangles(7)
    setup = nlos.confocal_setup(n=3, half_width=0.2, bins=150, dt=0.01, t0=0.3)
    layer = nlos.torch.RenderLayer(f, setup, visibility="off")
    m, k = np.meshgrid(np.arange(9), np.arange(150), indexing="ij")
    w = torch.from_numpy((np.cos(0.21 * k + 1.3 * m) + 0.3).astype(np.float32))
    x = torch.tensor(v, dtype=torch.float64, requires_grad=True)
    (layer(x).double() * w).sum().backward()
    grad = x.grad.numpy()

    def energy(q):
        with torch.no_grad():
            return float((layer(torch.from_numpy(q)).double() * w).sum())

    h = 2e-4
    for vi, c in [(0, 0), (1, 2), (5, 1), (11, 2)]:
        def e(d):
            q = v.copy()
            q[vi, c] += d
            return energy(q)

        fd = (-e(2 * h) + 8 * e(h) - 8 * e(-h) + e(-2 * h)) / (12 * h)
        assert abs(fd - grad[vi, c]) <= 2e-3 * max(abs(grad[vi, c]), 0.1 * np.abs(grad).max()), (vi, c, fd, grad[vi, c])
    assert x.grad.dtype == torch.float64


def test_the_example_lowers_its_loss_on_the_builtin_capture():
    example = runpy.run_path(str(WORKSPACE / "examples" / "python" / "fit_mesh_torch.py"))
    _, _, losses = example["fit"](WORKSPACE / "fixtures" / "builtin" / "capture.hdf5", steps=15)
    assert losses[-1] < 0.9 * losses[0], losses


def test_the_example_lowers_its_loss_on_a_shared_capture(tmp_path):
    bunny = shared("meshes/bunny_centered.obj")
    v, f = nlos.read_mesh(bunny)
    capture = nlos.render(v, f, nlos.confocal_setup(n=24, bins=600, dt=0.0024), photons=2000, seed=1)
    path = tmp_path / "bunny.hdf5"
    capture.save(path)
    example = runpy.run_path(str(WORKSPACE / "examples" / "python" / "fit_mesh_torch.py"))
    _, _, losses = example["fit"](path, steps=10)
    assert losses[-1] < losses[0], losses


def test_the_layer_refreshes_visibility_after_large_moves():
    # The front triangle of two moves aside: with `refresh` the layer renders what a new renderer does;
    # with refresh=None it keeps the visibility of its first vertices.
    front = np.array([[-0.3, -0.3, 0.3], [0.3, -0.3, 0.3], [0.0, 0.3, 0.3]], dtype=np.float32)
    v = np.concatenate([front, front + np.array([0.0, 0.0, 0.2], dtype=np.float32)])
    f = np.array([[0, 2, 1], [3, 5, 4]])
    setup = nlos.confocal_setup(n=3, half_width=0.05, bins=200, dt=0.01, t0=0.0)
    moved = v.copy()
    moved[:3, 0] += 5.0
    exact = nlos.Renderer(moved, f, setup).forward()
    layer, frozen = nlos.torch.RenderLayer(f, setup), nlos.torch.RenderLayer(f, setup, refresh=None)
    for lay in (layer, frozen):
        lay(torch.tensor(v))
    assert np.array_equal(layer(torch.tensor(moved)).numpy(), exact)
    assert frozen(torch.tensor(moved)).numpy().sum() < 0.7 * exact.sum()
    with pytest.raises(ValueError, match="refresh"):
        nlos.torch.RenderLayer(f, setup, refresh=0.0)
