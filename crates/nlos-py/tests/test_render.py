"""The renderer from Python: the same numbers as `nlos render`, the adjoint against finite differences,
typed errors for bad input."""

from __future__ import annotations

import os

import numpy as np
import pytest

import nlos
from conftest import random_triangles


def small_setup():
    return nlos.confocal_setup(n=3, half_width=0.2, bins=150, dt=0.01, t0=0.3)


def test_render_equals_the_command_bit_for_bit(tmp_path):
    v, f = random_triangles(3)
    mesh = tmp_path / "m.obj"
    nlos.write_mesh(mesh, v, f)
    setup = nlos.confocal_setup(n=8, half_width=0.25, bins=300, dt=0.004)
    setup_file = tmp_path / "setup.hdf5"
    setup.save(setup_file)
    out = tmp_path / "cli.hdf5"
    code = nlos.main(["render", str(mesh), "--out", str(out), "--setup", str(setup_file), "--photons", "500", "--seed", "4"])
    assert code == 0
    ours = nlos.render(*nlos.read_mesh(mesh), setup, photons=500, seed=4)
    assert np.array_equal(ours.data, nlos.load(out).data)
    clean_cli = tmp_path / "clean.hdf5"
    assert nlos.main(["render", str(mesh), "--out", str(clean_cli), "--setup", str(setup_file)]) == 0
    assert np.array_equal(nlos.render(v, f, setup).data, nlos.load(clean_cli).data)


def test_forward_is_a_new_array_of_the_setup_shape():
    v, f = random_triangles(1)
    r = nlos.Renderer(v, f, small_setup())
    a = r.forward()
    assert a.shape == r.shape == (9, 150) and a.dtype == np.float32 and a.sum() > 0
    assert not np.shares_memory(a, r.forward())


def test_the_models_are_named_once():
    assert nlos.BRDF_MODELS == ("lambert", "ggx", "retroreflective")
    with pytest.raises(ValueError, match='brdf: .*"lambert", "ggx" or "retroreflective"'):
        nlos.Renderer(*random_triangles(1), small_setup(), brdf="phong")


def five_point(e, h):
    return (-e(2 * h) + 8 * e(h) - 8 * e(-h) + e(-2 * h)) / (12 * h)


@pytest.mark.parametrize("brdf", [*nlos.BRDF_MODELS, "lambertian"])
def test_adjoint_matches_central_finite_differences(brdf):
    v, f = random_triangles(2)
    r = nlos.Renderer(v, f, small_setup(), brdf=brdf, albedo=0.3, visibility="off")
    m, k = np.meshgrid(np.arange(9), np.arange(150), indexing="ij")
    weights = (np.cos(0.21 * k + 1.3 * m) + 0.3).astype(np.float32)  # dE/dI of E = Σ w·I
    dv, dp = r.adjoint(weights)
    assert set(dp) == set(r.brdf_params)
    scale = np.abs(dv).max()

    def energy(vertices):
        r.set_vertices(vertices)
        return float(np.sum(r.forward().astype(np.float64) * weights))

    worst = 0.0
    for vi in range(len(v)):
        for c in range(3):
            def e(d, vi=vi, c=c):
                q = v.copy()
                q[vi, c] += d
                return energy(q)

            fd = five_point(e, 2e-4)  # truncation O(h^4); f32 rendering noise O(1/h)
            worst = max(worst, abs(fd - dv[vi, c]) / max(abs(dv[vi, c]), 0.1 * scale))
    assert worst < 2e-3, f"worst relative error {worst}"


def test_loss_and_grad_is_the_l2_loss_and_its_adjoint():
    v, f = random_triangles(4)
    setup = small_setup()
    r = nlos.Renderer(v, f, setup)
    measured = 0.8 * r.forward()
    loss, dv, _ = r.loss_and_grad(measured)
    rendered = r.forward().astype(np.float64)
    assert loss == pytest.approx(0.5 * np.sum((rendered - measured) ** 2), rel=1e-5)
    dv2, _ = r.adjoint((rendered - measured).astype(np.float32))
    assert np.allclose(dv, dv2, rtol=1e-5, atol=1e-12)
    with pytest.raises(ValueError, match="loss"):
        r.loss_and_grad(measured, loss="l1")


@pytest.mark.parametrize(
    "vertices, faces, message",
    [
        (np.zeros((3, 2)), [[0, 1, 2]], "vertices: shape"),
        ([[0, 0, 0.4], [0.1, 0, 0.4], [0, np.nan, 0.4]], [[0, 1, 2]], "vertices: element 7"),
        ([[0, 0, 0.4], [0.1, 0, 0.4], [0, 0.1, 0.4]], [[0, 1, 3]], "faces: face 0 corner 2 is 3"),
        ([[0, 0, 0.4], [0.1, 0, 0.4], [0, 0.1, 0.4]], [[0, -1, 2]], "faces: face 0 corner 1 is -1"),
        ([[0, 0, 0.4], [0.1, 0, 0.4], [0, 0.1, 0.4]], [[0.0, 1.0, 2.0]], "faces: dtype"),
        ([[0, 0, 0.4], [0.1, 0, 0.4], [0, 0.1, 0.4]], [[0, 1]], "faces: shape"),
    ],
)
def test_bad_meshes_raise_value_errors_naming_the_argument(vertices, faces, message):
    with pytest.raises(ValueError, match=message):
        nlos.Renderer(np.asarray(vertices, dtype=np.float32), np.asarray(faces), small_setup())


def test_bad_options_and_shapes_raise_value_errors():
    v, f = random_triangles(5)
    setup = small_setup()
    for kwargs, message in [
        ({"brdf": "phong"}, "brdf"),
        ({"kernel": "gauss"}, "kernel"),
        ({"sampling": "mc"}, "sampling"),
        ({"visibility": "maybe"}, "visibility"),
        ({"vis_level": 99}, "vis_level"),
        ({"albedo": -1.0}, "albedo"),
        ({"brdf": "ggx", "alpha": 0.0}, "alpha"),
        ({"device": "tpu"}, "device"),
    ]:
        with pytest.raises(ValueError, match=message):
            nlos.Renderer(v, f, setup, **kwargs)
    r = nlos.Renderer(v, f, setup)
    with pytest.raises(ValueError, match="d_loss: shape"):
        r.adjoint(np.zeros((9, 149), dtype=np.float32))
    with pytest.raises(ValueError, match="vertices: shape"):
        r.set_vertices(v[:-1])
    with pytest.raises(ValueError, match="photons"):
        nlos.render(v, f, setup, photons=-5)


def test_no_panic_reaches_python_on_degenerate_input():
    # A degenerate triangle and an empty mesh render nothing; a zero-sized setup is a typed error.
    v = np.array([[0, 0, 0.4], [0, 0, 0.4], [0, 0, 0.4]], dtype=np.float32)
    assert nlos.Renderer(v, [[0, 1, 2]], small_setup()).forward().sum() == 0
    empty = nlos.Renderer(np.zeros((0, 3), dtype=np.float32), np.zeros((0, 3), dtype=np.int64), small_setup())
    assert empty.forward().sum() == 0
    with pytest.raises(ValueError, match="grid"):
        nlos.confocal_setup(n=0)
    with pytest.raises(ValueError):
        nlos.confocal_setup(bins=0)


def test_reflectance_is_settable_and_fits_by_its_gradients():
    v, f = random_triangles(5)
    setup = small_setup()
    truth = nlos.Renderer(v, f, setup, brdf="ggx", albedo=0.4, alpha=0.25, specular=0.6)
    measured = truth.forward()
    r = nlos.Renderer(v, f, setup, brdf="ggx", albedo=0.7, alpha=0.25, specular=0.6)
    assert r.reflectance["albedo_diffuse"] == pytest.approx(0.7) and set(r.reflectance) == set(r.brdf_params)
    # Sign descent on the diffuse albedo alone (the step halves whenever the gradient turns), through
    # set_reflectance and the gradients' own parameter names.
    losses, step, previous = [], 0.1, 0.0
    for _ in range(30):
        loss, _, grads = r.loss_and_grad(measured)
        losses.append(loss)
        g = grads["albedo_diffuse"]
        if g * previous < 0:
            step *= 0.5
        previous = g
        r.set_reflectance({"albedo_diffuse": r.reflectance["albedo_diffuse"] - step * np.sign(g)})
    assert losses[-1] < 0.05 * losses[0]
    assert r.reflectance["albedo_diffuse"] == pytest.approx(0.4, abs=0.02)
    assert r.reflectance["alpha"] == pytest.approx(0.25), "the parameters not set keep their values"
    with pytest.raises(ValueError, match='reflectance: "roughness"'):
        r.set_reflectance({"roughness": 0.1})
    with pytest.raises(ValueError, match="reflectance"):
        r.set_reflectance({"alpha": -1.0})


def test_refresh_visibility_follows_the_vertices():
    # Two triangles, one behind the other: moving the front one aside uncovers the back one only once
    # the cached visibility is recomputed.
    front = np.array([[-0.3, -0.3, 0.3], [0.3, -0.3, 0.3], [0.0, 0.3, 0.3]], dtype=np.float32)
    back = front + np.array([0.0, 0.0, 0.2], dtype=np.float32)
    v = np.concatenate([front, back])
    f = np.array([[0, 2, 1], [3, 5, 4]])
    setup = nlos.confocal_setup(n=3, half_width=0.05, bins=200, dt=0.01, t0=0.0)
    r = nlos.Renderer(v, f, setup)
    moved = v.copy()
    moved[:3, 0] += 5.0  # the front triangle far to the side
    r.set_vertices(moved)
    stale = r.forward()
    r.refresh_visibility()
    fresh = r.forward()
    exact = nlos.Renderer(moved, f, setup).forward()
    assert np.array_equal(fresh, exact) and fresh.sum() > 1.5 * stale.sum()


def test_device_gpu_matches_the_cpu_or_says_why_not():
    """`device="gpu"`: the same transient and gradients as the CPU (to f32 rounding) where the machine has a GPU
    adapter (Mesa's lavapipe counts), a RenderError naming the reason where it has none or the setting has no GPU
    version; `"auto"` never fails. Without an adapter it skips, or fails under NLOS_REQUIRE_GPU=1 (CI)."""
    v, f = random_triangles(6)
    setup = nlos.confocal_setup(n=4, half_width=0.2, bins=200, dt=0.005, t0=0.3)
    cpu = nlos.Renderer(v, f, setup)
    assert cpu.device == "cpu"
    assert nlos.Renderer(v, f, setup, device="auto").device in ("cpu", "gpu")
    with pytest.raises(nlos.RenderError, match="GPU"):
        nlos.Renderer(v, f, setup, visibility="live", device="gpu")
    try:
        gpu = nlos.Renderer(v, f, setup, device="gpu")
    except nlos.RenderError as e:
        assert "no GPU adapter" in str(e) or "no GPU backend" in str(e)
        if os.environ.get("NLOS_REQUIRE_GPU", "") not in ("", "0"):
            pytest.fail(f"no GPU adapter and NLOS_REQUIRE_GPU is set (CI installs lavapipe): {e}")
        pytest.skip(f"no GPU here: {e}")
    assert gpu.device == "gpu"
    a, b = cpu.forward(), gpu.forward()
    assert a.sum() > 0 and np.max(np.abs(a - b)) <= 1e-4 * np.max(np.abs(a))
    d = np.cos(np.arange(a.size, dtype=np.float32)).reshape(a.shape)
    (ga, pa), (gb, pb) = cpu.adjoint(d), gpu.adjoint(d)
    top = np.max(np.abs(ga))
    assert top > 0 and np.max(np.abs(ga - gb)) <= 1e-4 * top
    assert abs(pa["albedo"] - pb["albedo"]) <= 1e-4 * abs(pa["albedo"])
