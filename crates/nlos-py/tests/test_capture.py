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
