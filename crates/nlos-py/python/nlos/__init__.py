"""Non-line-of-sight surface reconstruction from Python.

Captures are NumPy arrays (``nlos.load``), the differentiable transient renderer gives renderings and
gradients (``nlos.Renderer``; ``nlos.torch.render`` for PyTorch), and ``nlos.reconstruct`` runs the same
pipeline as ``nlos reconstruct`` on the command line. Every heavy step is Rust, run with the GIL released.

Units: metres; time is path length (laser spot -> hidden point -> sensor spot); the relay wall is the
plane z = 0 with the hidden scene at z > 0.
"""

from __future__ import annotations

import json
import os
from typing import Any, Callable, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from . import _nlos
from ._nlos import (
    Capture,
    CaptureError,
    ConfigError,
    InitError,
    MeshError,
    NlosError,
    ReconstructError,
    RenderError,
    Renderer,
    __version__,
    confocal_setup,
    load,
    read_mesh,
    render,
    write_mesh,
)

__all__ = [
    "Capture",
    "CaptureError",
    "ConfigError",
    "InitError",
    "MeshError",
    "NlosError",
    "ReconstructError",
    "RenderError",
    "Renderer",
    "__version__",
    "confocal_setup",
    "default_settings",
    "eval",
    "fbp",
    "fk",
    "initial_surface",
    "lct",
    "load",
    "main",
    "read_mesh",
    "reconstruct",
    "render",
    "write_mesh",
]

PathLike = Union[str, "os.PathLike[str]"]
Mesh = Tuple[np.ndarray, np.ndarray]


def _from_tal(obj: Any) -> Capture:
    """A :class:`Capture` from a y-tal capture object (duck-typed: ``H``, ``H_format``, ``sensor_grid_xyz``,
    ``laser_grid_xyz``, ``delta_t``, ``t_start``), as ``tal.io.read_capture`` returns it.

    Confocal captures (``H_format`` of a single grid, or equal laser and sensor grids) keep their grid;
    time is along the first axis of ``H`` in y-tal's convention.
    """
    data = np.asarray(obj.H, dtype=np.float32)
    sensors = np.asarray(obj.sensor_grid_xyz, dtype=np.float32)
    lasers = getattr(obj, "laser_grid_xyz", None)
    lasers = None if lasers is None else np.asarray(lasers, dtype=np.float32)
    grid = sensors.shape[:2] if sensors.ndim == 3 else None
    sensors = sensors.reshape(-1, 3)
    if lasers is not None:
        lasers = lasers.reshape(-1, 3)
        if lasers.shape == sensors.shape and np.array_equal(lasers, sensors):
            lasers = None
    bins = data.shape[0]
    # y-tal stores H as (time, sensor x, sensor y) or (time, laser…, sensor…): time first.
    rows = np.moveaxis(data, 0, -1).reshape(-1, bins)
    if grid is not None:
        # y-tal's grids are indexed [x, y]; nlos's rows run x fastest (spot ix + nx·iy).
        nx, ny = grid
        rows = rows.reshape(nx, ny, bins).transpose(1, 0, 2).reshape(-1, bins)
        sensors = np.asarray(obj.sensor_grid_xyz, dtype=np.float32).transpose(1, 0, 2).reshape(-1, 3)
    t0 = float(getattr(obj, "t_start", 0.0) or 0.0)
    return Capture.from_arrays(
        np.ascontiguousarray(rows),
        sensors,
        dt=float(obj.delta_t),
        t0=t0,
        laser_points=lasers,
        grid=(int(grid[0]), int(grid[1])) if grid is not None and lasers is None else None,
    )


Capture.from_tal = staticmethod(_from_tal)  # type: ignore[attr-defined]


def default_settings() -> Dict[str, Any]:
    """Every setting of a reconstruction with its default, as nested dicts (the sections of
    ``nlos reconstruct --print-config``)."""
    return json.loads(_nlos.default_settings())


def _settings_json(settings: Dict[str, Any]) -> str:
    return json.dumps(settings)


def lct(capture: Capture, snr: Optional[float] = None) -> Tuple[np.ndarray, Dict[str, Tuple[float, float]]]:
    """Light-cone transform (O'Toole et al. 2018) of a confocal capture.

    Returns ``(volume, axes)``: ``volume[ix, iy, iz]`` (float32) and, for ``"x"``, ``"y"``, ``"z"``, the
    first voxel centre and the spacing in metres.
    """
    return _nlos.volume(capture, "lct", snr)


def fk(capture: Capture) -> Tuple[np.ndarray, Dict[str, Tuple[float, float]]]:
    """f-k migration (Lindell et al. 2019) of a confocal capture; see :func:`lct` for the result."""
    return _nlos.volume(capture, "fk")


def fbp(capture: Capture) -> Tuple[np.ndarray, Dict[str, Tuple[float, float]]]:
    """Filtered back-projection of a capture; see :func:`lct` for the result."""
    return _nlos.volume(capture, "fbp")


def _capture(capture: Union[Capture, PathLike]) -> Capture:
    return capture if isinstance(capture, Capture) else load(capture)


def initial_surface(capture: Union[Capture, PathLike], **settings: Any) -> Mesh:
    """The start surface ``nlos reconstruct`` would begin from: ``(vertices, faces)``.

    ``settings`` are sections of the settings (see :func:`default_settings`), e.g. ``init="fk"``.
    """
    return _nlos.initial_surface(_capture(capture), _settings_json(settings))


def reconstruct(
    capture: Union[Capture, PathLike],
    out: Optional[PathLike] = None,
    *,
    resume: bool = False,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    **settings: Any,
) -> Dict[str, Any]:
    """Reconstructs the hidden surface with the pipeline of ``nlos reconstruct``.

    Parameters
    ----------
    capture
        A :class:`Capture` or a path to any supported capture file.
    out
        Run directory: ``mesh.obj``, ``init.obj``, ``settings.toml``, the run log and checkpoints.
    resume
        Continue the run in ``out`` from its checkpoint, with the settings it was started with
        (``out/settings.toml``; settings given here change them, and a change the run cannot take is a
        ``ConfigError`` naming it).
    progress
        Called after every iteration with a dict (stage, iteration, iterations_planned, loss, faces,
        elapsed_s).
    **settings
        Sections of the settings, e.g. ``schedule={"max_stages": 2}, seed=1, init="fk"``
        (:func:`default_settings` lists them).

    Returns
    -------
    dict
        ``vertices`` (n, 3) float32, ``faces`` (m, 3) uint32, ``reflectance`` and ``log`` (dicts),
        ``stop`` (why it ended), ``scale`` and ``notes`` (what the pipeline decided).

    Raises
    ------
    ConfigError
        An unknown setting or a value out of range.
    KeyboardInterrupt
        On Ctrl-C, after the current block's checkpoint is written (resume with ``resume=True``).
    """
    result = _nlos.reconstruct(
        _capture(capture),
        _settings_json(settings),
        None if out is None else os.fspath(out),
        resume,
        progress,
    )
    for key in ("reflectance", "log", "stop"):
        result[key] = json.loads(result[key])
    return result


def eval(  # noqa: A001 - the name of the command it mirrors
    mesh: Union[Mesh, PathLike], gt: Union[Mesh, PathLike], grid: int = 128
) -> Dict[str, Any]:
    """The metrics of ``nlos eval``: coverage and depth errors on a ``grid`` x ``grid`` +z ray grid over
    [-0.25, 0.25]^2 m, Chamfer and Hausdorff distances, normal error (lengths in metres).

    ``mesh`` and ``gt`` are paths or ``(vertices, faces)`` pairs.
    """
    return json.loads(_nlos.evaluate(mesh, gt, grid))


def main(argv: Optional[Sequence[str]] = None) -> int:
    """The ``nlos`` command line, in this process (``pip install`` puts it on the PATH as ``nlos``)."""
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    return _nlos.cli(args)
