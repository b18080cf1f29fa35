"""Volumes, the start surface, the reconstruction pipeline and the metrics, on the built-in fixture."""

from __future__ import annotations

import numpy as np
import pytest

import nlos

FAST = {"schedule": {"max_stages": 1, "initial_resolution": 12, "max_blocks_per_stage": 1, "shape_iterations": 3}}
DEMO = {"schedule": {"max_stages": 2, "initial_resolution": 20, "max_blocks_per_stage": 2, "shape_iterations": 15}}


@pytest.mark.parametrize("method", ["lct", "fk", "fbp"])
def test_volumes_peak_at_the_patch_depth(builtin_capture, method):
    volume, axes = getattr(nlos, method)(nlos.load(builtin_capture))
    assert volume.ndim == 3 and volume.dtype == np.float32 and volume.shape[:2] == (24, 24)
    z0, dz = axes["z"]
    iz = np.unravel_index(np.argmax(np.abs(volume)), volume.shape)[2]
    # The built-in patch lies at 0.36-0.40 m.
    assert 0.33 < z0 + iz * dz < 0.43


def test_reconstruct_improves_on_its_start(builtin_capture, builtin_truth, tmp_path):
    capture = nlos.load(builtin_capture)
    start = nlos.initial_surface(capture)
    seen = []
    result = nlos.reconstruct(capture, tmp_path / "run", progress=seen.append, seed=1, **DEMO)
    assert result["stop"] and result["faces"].shape[1] == 3 and result["vertices"].dtype == np.float32
    assert seen and seen[-1]["iteration"] >= 1 and "loss" in seen[-1]
    for name in ["mesh.obj", "init.obj", "settings.toml", "run_log.json", "checkpoint.json"]:
        assert (tmp_path / "run" / name).is_file(), name
    before, after = nlos.eval(start, builtin_truth), nlos.eval((result["vertices"], result["faces"]), builtin_truth)
    assert after["depth_error_mean"] < 0.5 * before["depth_error_mean"]
    assert after["chamfer"] < 0.5 * before["chamfer"]
    assert after["coverage"] > 0.9
    # The same settings through the command line give the same mesh.
    cli_run = tmp_path / "cli"
    args = ["reconstruct", str(builtin_capture), "--out", str(cli_run), "--quiet", "--no-report", "--seed", "1"]
    for key, value in DEMO["schedule"].items():
        args += ["--set", f"schedule.{key}={value}"]
    assert nlos.main(args) == 0
    v, f = nlos.read_mesh(cli_run / "mesh.obj")
    assert np.array_equal(v, result["vertices"]) and np.array_equal(f, result["faces"])


def test_a_finished_run_resumes_to_the_same_mesh(builtin_capture, tmp_path):
    first = nlos.reconstruct(builtin_capture, tmp_path, **FAST)
    again = nlos.reconstruct(builtin_capture, tmp_path, resume=True, **FAST)
    assert np.array_equal(first["vertices"], again["vertices"])
    with pytest.raises(nlos.ConfigError, match="shape_iterations"):
        nlos.reconstruct(builtin_capture, tmp_path, resume=True, schedule={**FAST["schedule"], "shape_iterations": 4})


def test_bad_settings_raise_config_errors(builtin_capture):
    with pytest.raises(nlos.ConfigError, match="no_such_section"):
        nlos.reconstruct(builtin_capture, no_such_section={})
    with pytest.raises(nlos.ConfigError, match="max_stages"):
        nlos.reconstruct(builtin_capture, schedule={"max_stages": "many"})
    with pytest.raises(nlos.ConfigError):
        nlos.reconstruct(builtin_capture, resume=True)
    assert "schedule" in nlos.default_settings()


def test_a_progress_callback_that_raises_stops_the_run(builtin_capture):
    def boom(_):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        nlos.reconstruct(builtin_capture, progress=boom, **FAST)


def test_eval_and_mesh_files(builtin_truth, tmp_path):
    v, f = nlos.read_mesh(builtin_truth)
    m = nlos.eval((v, f), builtin_truth)
    assert m["coverage"] == 1.0 and m["depth_error_max"] == 0.0
    nlos.write_mesh(tmp_path / "t.ply", v, f)
    v2, f2 = nlos.read_mesh(tmp_path / "t.ply")
    assert np.array_equal(v, v2) and np.array_equal(f, f2)
    with pytest.raises(nlos.MeshError, match="nope.obj"):
        nlos.read_mesh(tmp_path / "nope.obj")
    with pytest.raises(TypeError, match="mesh"):
        nlos.eval(3.0, builtin_truth)
    with pytest.raises(ValueError, match="grid"):
        nlos.eval((v, f), builtin_truth, grid=0)


def test_an_interrupt_stops_after_the_block_checkpoint_and_the_run_resumes(builtin_capture, tmp_path):
    # Ctrl-C reaches the run as KeyboardInterrupt, raised either by the progress callback's Python code or
    # by the signal check between iterations; both stop the run after the current block's checkpoint.
    def progress(p):
        if p["iteration"] == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        nlos.reconstruct(builtin_capture, tmp_path, progress=progress, **DEMO)
    assert (tmp_path / "checkpoint.json").is_file(), "the block's checkpoint is written before stopping"
    assert not (tmp_path / "mesh.obj").exists(), "the run stopped before its end"
    done = nlos.reconstruct(builtin_capture, tmp_path, resume=True, **DEMO)
    assert done["stop"] != "interrupted" and len(done["faces"]) > 0


def test_sigint_during_the_run_stops_it_after_the_block_checkpoint(builtin_capture, tmp_path):
    import subprocess
    import sys
    import textwrap

    # In a child process, so that a stray KeyboardInterrupt cannot reach pytest: SIGINT arrives from
    # another thread while the run is inside Rust (GIL released), as Ctrl-C does.
    script = textwrap.dedent(
        f"""
        import os, signal, sys, threading, nlos
        # Python maps SIGINT to KeyboardInterrupt unless it started with SIGINT ignored (as a background
        # job of a non-interactive shell does): install the mapping, as an interactive session has it.
        signal.signal(signal.SIGINT, signal.default_int_handler)
        def progress(p):
            if p["iteration"] == 1:
                threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
        try:
            nlos.reconstruct({str(builtin_capture)!r}, {str(tmp_path)!r}, progress=progress, **{DEMO!r})
        except KeyboardInterrupt:
            sys.exit(3)
        """
    )
    p = subprocess.run([sys.executable, "-c", script], timeout=300)
    assert p.returncode == 3
    assert (tmp_path / "checkpoint.json").is_file() and not (tmp_path / "mesh.obj").exists()


def _as_set_flags(settings, prefix=""):
    """``nlos reconstruct --set KEY=VALUE`` flags for a settings dict."""
    flags = []
    for key, value in settings.items():
        if isinstance(value, dict):
            flags += _as_set_flags(value, f"{prefix}{key}.")
        else:
            flags += ["--set", f"{prefix}{key}={value}"]
    return flags


def _without_times(value):
    """A run's JSON without its wall-clock fields (``time_s``, ``elapsed_s``, ``seconds``: the only
    non-deterministic ones)."""
    if isinstance(value, dict):
        return {k: _without_times(v) for k, v in value.items() if k not in ("time_s", "elapsed_s", "seconds")}
    if isinstance(value, list):
        return [_without_times(v) for v in value]
    return value


def _log_without_times(run_dir, name="run_log.json"):
    import json

    return _without_times(json.loads((run_dir / name).read_text()))


def test_the_cli_and_python_write_the_same_run_directory_and_resume_each_others_runs(builtin_capture, tmp_path):
    cli_dir, py_dir, mixed_dir = tmp_path / "cli", tmp_path / "py", tmp_path / "mixed"
    flags = ["--quiet", "--no-report", *_as_set_flags(DEMO)]
    assert nlos.main(["reconstruct", str(builtin_capture), "--out", str(cli_dir), *flags]) == 0
    nlos.reconstruct(builtin_capture, py_dir, **DEMO)
    written = sorted(p.name for p in cli_dir.iterdir() if p.name != "command.json")
    assert sorted(p.name for p in py_dir.iterdir()) == written
    for name in written:
        if name.endswith(".json"):
            assert _log_without_times(cli_dir, name) == _log_without_times(py_dir, name), name
        else:
            assert (cli_dir / name).read_bytes() == (py_dir / name).read_bytes(), name

    # Started from Python, stopped after its first block, resumed by the command line with the run's own
    # settings (no flags): the same run as the uninterrupted ones.
    def stop(p):
        if p["iteration"] == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        nlos.reconstruct(builtin_capture, mixed_dir, progress=stop, **DEMO)
    settings = (mixed_dir / "settings.toml").read_bytes()
    assert nlos.main(["reconstruct", str(builtin_capture), "--out", str(mixed_dir), "--resume", "--quiet", "--no-report"]) == 0
    assert (mixed_dir / "mesh.obj").read_bytes() == (cli_dir / "mesh.obj").read_bytes()
    assert _log_without_times(mixed_dir) == _log_without_times(cli_dir)
    # And the finished command-line run resumes from Python without settings: its own are used, unchanged.
    again = nlos.reconstruct(builtin_capture, cli_dir, resume=True)
    assert len(again["faces"]) > 0 and (mixed_dir / "settings.toml").read_bytes() == settings
    assert (cli_dir / "settings.toml").read_bytes() == settings
