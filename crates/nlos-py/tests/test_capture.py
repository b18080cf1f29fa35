"""Captures: loading, NumPy views, arrays in, every writable format round trip, typed errors."""

from __future__ import annotations

import numpy as np
import pytest

import nlos
from conftest import shared


def test_load_gives_the_histograms_without_a_copy(builtin_capture):
    c = nlos.load(builtin_capture)
    assert c.format == "tal" and c.confocal and c.grid == (24, 24)
    assert c.data.shape == (576, 512) and c.data.dtype == np.float32
    first, second = c.data, c.data
    assert first is second, "data must be the capture's own array, the same object on every access"
    assert c.dt == pytest.approx(0.0024) and c.t0 == 0.0 and c.bins == 512
    assert c.scan_points.shape == (576, 3)
    assert c.data.sum() > 0
    # Writes go to the capture itself.
    c.data[0, 0] = 123.0
    assert c.data[0, 0] == 123.0


@pytest.mark.parametrize("ext", ["hdf5", "npy", "exr"])
def test_every_writable_format_round_trips(builtin_capture, tmp_path, ext):
    c = nlos.load(builtin_capture)
    out = tmp_path / f"c.{ext}"
    c.save(out)
    back = nlos.load(out)
    assert np.array_equal(back.data, c.data)
    assert np.array_equal(back.scan_points, c.scan_points)
    assert (back.t0, back.dt, back.bins, back.grid) == (c.t0, c.dt, c.bins, c.grid)


def test_from_arrays_confocal_and_exhaustive(tmp_path):
    rng = np.random.default_rng(0)
    spots = np.stack(np.meshgrid(np.linspace(-0.2, 0.2, 4), np.linspace(-0.2, 0.2, 3)), -1).reshape(-1, 2)
    spots = np.c_[spots, np.zeros(len(spots))].astype(np.float32)
    data = rng.random((12, 50), dtype=np.float32)
    c = nlos.Capture.from_arrays(data, spots, dt=0.01, t0=0.3, grid=(4, 3))
    assert c.confocal and c.grid == (4, 3) and np.array_equal(c.data, data)
    lasers = spots[:2]
    e = nlos.Capture.from_arrays(rng.random((24, 50)), spots, dt=0.01, laser_points=lasers)
    assert not e.confocal and e.measurements == 24
    e.save(tmp_path / "e.hdf5")
    assert np.allclose(nlos.load(tmp_path / "e.hdf5").data, e.data)


def test_from_tal_reads_a_y_tal_capture_object():
    class TalCapture:  # the attributes y-tal's capture object has
        pass

    nx, ny, bins = 4, 3, 20
    xs, ys = np.linspace(-0.2, 0.2, nx), np.linspace(-0.1, 0.1, ny)
    grid = np.zeros((nx, ny, 3), dtype=np.float32)
    grid[..., 0], grid[..., 1] = np.meshgrid(xs, ys, indexing="ij")
    tal = TalCapture()
    tal.H = np.random.default_rng(1).random((bins, nx, ny)).astype(np.float32)
    tal.sensor_grid_xyz = grid
    tal.laser_grid_xyz = grid
    tal.delta_t, tal.t_start = 0.004, 0.1
    c = nlos.Capture.from_tal(tal)
    assert c.confocal and c.grid == (nx, ny) and c.bins == bins
    # Spot ix + nx·iy is sensor grid [ix, iy]: x fastest.
    ix, iy = 2, 1
    assert np.allclose(c.scan_points[ix + nx * iy], grid[ix, iy])
    assert np.allclose(c.data[ix + nx * iy], tal.H[:, ix, iy])
    assert c.dt == pytest.approx(0.004) and c.t0 == pytest.approx(0.1)


@pytest.mark.parametrize(
    "data, points, message",
    [
        (np.zeros((3, 10)), np.zeros((2, 3)), "data: shape"),
        (np.zeros((2, 10)), np.zeros((2, 2)), "scan_points: shape"),
        (np.full((2, 10), np.nan), np.zeros((2, 3)), "data: element 0"),
        (np.zeros((2, 10), dtype=np.int32), np.zeros((2, 3)), "data: dtype"),
        (np.zeros((2, 10)), np.array([[0, 0, np.inf], [0, 0, 0]]), "scan_points: element 2"),
    ],
)
def test_bad_arrays_raise_value_errors_naming_the_argument(data, points, message):
    with pytest.raises(ValueError, match=message):
        nlos.Capture.from_arrays(data, points, dt=0.01)


def test_bad_time_axis_and_grid_raise_value_errors():
    with pytest.raises(ValueError, match="t0, dt"):
        nlos.Capture.from_arrays(np.zeros((1, 4)), np.zeros((1, 3)), dt=-1.0)
    with pytest.raises(ValueError, match="grid"):
        nlos.Capture.from_arrays(np.zeros((2, 4)), np.zeros((2, 3)), dt=0.1, grid=(3, 3))


def test_bad_files_raise_capture_errors_naming_the_file(tmp_path):
    missing = tmp_path / "missing.mat"
    with pytest.raises(nlos.CaptureError, match="missing.mat"):
        nlos.load(missing)
    garbage = tmp_path / "garbage.hdf5"
    garbage.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 40)
    with pytest.raises(nlos.CaptureError, match="garbage.hdf5"):
        nlos.load(garbage)
    assert issubclass(nlos.CaptureError, nlos.NlosError)


def test_saving_to_an_unknown_extension_is_a_value_error(builtin_capture, tmp_path):
    with pytest.raises(ValueError, match="extension"):
        nlos.load(builtin_capture).save(tmp_path / "c.xyz")


def test_reads_a_real_stanford_capture():
    c = nlos.load(shared("measured/data_diffuse_s.mat"))
    assert c.format == "lct-mat" and c.grid == (64, 64) and c.bins == 2048


def curved_pairs(n: int = 6):
    """n laser/sensor pairs 0.27 m apart on a wall bent by ±3 cm, with the bend's normals."""
    x = np.linspace(-0.2, 0.2, n)
    lasers = np.stack([x, np.zeros(n), 0.03 * np.cos(4 * x)], axis=1).astype(np.float32)
    sensors = lasers.copy()
    sensors[:, 0] -= 0.27
    sensors[:, 2] = 0.03 * np.cos(4 * sensors[:, 0])
    normal = lambda p: np.stack([0.12 * np.sin(4 * p[:, 0]), np.zeros(len(p)), np.ones(len(p))], axis=1)
    unit = lambda v: (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32)
    return lasers, sensors, unit(normal(lasers)), unit(normal(sensors))


def test_paired_captures_on_a_curved_wall_round_trip(tmp_path):
    lasers, sensors, n_l, n_s = curved_pairs()
    data = np.arange(6 * 5, dtype=np.float32).reshape(6, 5)
    c = nlos.Capture.from_arrays(data, sensors, laser_points=lasers, pattern="paired", dt=0.01)
    assert c.pattern == "paired" and not c.confocal and c.measurements == 6
    assert np.all(c.scan_normals == np.array([0, 0, 1], dtype=np.float32))
    c = c.with_normals(n_s, n_l)
    np.testing.assert_array_equal(c.laser_normals, n_l)
    np.testing.assert_array_equal(c.scan_normals, n_s)
    assert "paired: 6 laser spots (a list), each recorded at its own sensor spot" in repr(c)
    for ext in ["npy", "exr"]:
        c.save(tmp_path / f"p.{ext}")
        back = nlos.load(tmp_path / f"p.{ext}")
        assert back.pattern == "paired"
        np.testing.assert_array_equal(back.data, data)
        np.testing.assert_array_equal(back.laser_points, lasers)
        np.testing.assert_array_equal(back.scan_normals, n_s)
    # y-tal's HDF5 has no paired layout: a typed error that says what to write instead.
    with pytest.raises(nlos.CaptureError, match=r"\.npy"):
        c.save(tmp_path / "p.hdf5")


def test_bad_pairings_raise_typed_errors():
    lasers, sensors, n_l, n_s = curved_pairs()
    data = np.zeros((6, 5), dtype=np.float32)
    with pytest.raises(nlos.CaptureError, match="sensor_points"):
        nlos.Capture.from_arrays(np.zeros((5, 5), np.float32), sensors[:5], laser_points=lasers, pattern="paired", dt=0.01)
    with pytest.raises(ValueError, match="pattern"):
        nlos.Capture.from_arrays(data, sensors, pattern="paired", dt=0.01)
    with pytest.raises(ValueError, match="pattern"):
        nlos.Capture.from_arrays(data, sensors, laser_points=lasers, pattern="pairs", dt=0.01)
    behind = lasers.copy()
    behind[2, 2] = -0.6
    with pytest.raises(nlos.CaptureError, match="behind the wall"):
        nlos.Capture.from_arrays(data, sensors, laser_points=behind, pattern="paired", dt=0.01)
    c = nlos.Capture.from_arrays(data, sensors, laser_points=lasers, pattern="paired", dt=0.01)
    with pytest.raises(nlos.CaptureError, match="normals"):
        c.with_normals(2 * n_s)
    with pytest.raises(ValueError, match="scan_normals"):
        c.with_normals(n_s[:3])


def test_reads_the_general_nlos_capture_with_its_bin_width():
    path = shared("measured/general_nlos/data.mat")
    with pytest.raises(nlos.CaptureError, match="bin_width_ps=32"):
        nlos.load(path)
    c = nlos.load(path, bin_width_ps=32)
    assert c.format == "general-nlos" and c.pattern == "paired"
    assert c.data.shape == (4096, 512) and c.dt == pytest.approx(0.0096)
    gaps = np.linalg.norm(c.laser_points - c.scan_points, axis=1)
    assert gaps.min() > 0.24 and gaps.max() < 0.29
