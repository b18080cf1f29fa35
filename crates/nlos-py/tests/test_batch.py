"""Batches beyond one process: several captures reconstructed on a Dask cluster (a LocalCluster of worker
processes, through ``examples/python/batch_dask.py``) give exactly what one-by-one runs give. Dask is
installed in CI; elsewhere the test skips without it (and fails under NLOS_REQUIRE_DATA=1)."""

from __future__ import annotations

import runpy

import numpy as np
import pytest

import nlos
from conftest import WORKSPACE, require_data

FAST = {"schedule": {"max_stages": 1, "initial_resolution": 12, "max_blocks_per_stage": 2, "shape_iterations": 3}}


@pytest.fixture
def distributed():
    try:
        import dask.distributed
    except ImportError:
        if require_data():
            pytest.fail("dask.distributed is not installed and NLOS_REQUIRE_DATA is set (CI installs it)")
        pytest.skip("dask.distributed is not installed")
    return dask.distributed


def test_a_dask_batch_equals_one_by_one_runs(builtin_capture, tmp_path, distributed):
    # Two captures: the built-in one and its scan cut to 24 x 16 spots.
    full = nlos.load(builtin_capture)
    nx, ny = full.grid
    rows = slice(4, 20)
    cut = nlos.Capture.from_arrays(
        full.data.reshape(ny, nx, -1)[rows].reshape(-1, full.bins),
        full.scan_points.reshape(ny, nx, 3)[rows].reshape(-1, 3),
        dt=full.dt,
        t0=full.t0,
        grid=(nx, 16),
    )
    captures = [str(builtin_capture), str(tmp_path / "cut.hdf5")]
    cut.save(captures[1])
    example = runpy.run_path(str(WORKSPACE / "examples" / "python" / "batch_dask.py"))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster:
        with distributed.Client(cluster) as client:
            batch = example["reconstruct_many"](client, captures, str(tmp_path / "batch"), **FAST)
    for i, (capture, result) in enumerate(zip(captures, batch)):
        alone = nlos.reconstruct(capture, tmp_path / "alone" / str(i), **FAST)
        assert np.array_equal(result.vertices, alone.vertices) and np.array_equal(result.faces, alone.faces)
        assert result.stop == alone.stop == "max_stages"
    assert (tmp_path / "batch" / "capture" / "mesh.obj").is_file() and (tmp_path / "batch" / "cut" / "mesh.obj").is_file()
    assert len(batch[0].faces) != len(batch[1].faces), "the two captures are different reconstructions"
