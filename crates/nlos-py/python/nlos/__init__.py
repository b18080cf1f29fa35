"""Non-line-of-sight surface reconstruction from Python.

Captures are NumPy arrays (``nlos.load``), the differentiable transient renderer gives renderings and
gradients (``nlos.Renderer``; ``nlos.torch.render`` for PyTorch), and ``nlos.reconstruct`` runs the same
pipeline as ``nlos reconstruct`` on the command line. Every heavy step is Rust, run with the GIL released.

Units: metres; time is path length (laser spot -> hidden point -> sensor spot); the relay wall is the
plane z = 0 with the hidden scene at z > 0.

Axis orders, the same everywhere: a capture's ``data`` is ``[measurement, bin]`` with measurement
``ix + nx * iy`` on a grid (so ``data.reshape(ny, nx, bins)`` is ``[iy, ix, bin]``); a volume is
``[iy, ix, iz]``; vertices are ``(n, 3)`` float32 ``(x, y, z)`` rows and faces ``(m, 3)`` vertex indices.
"""

from __future__ import annotations

import dataclasses
import json
import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _nlos
from ._nlos import (
    BRDF_MODELS,
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
    "BRDF_MODELS",
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
    "Metrics",
    "Reconstruction",
    "Volume",
    "default_settings",
    "evaluate",
    "fbp",
    "fk",
    "initial_surface",
    "lct",
    "load",
    "pf",
    "main",
    "read_mesh",
    "read_run",
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


@dataclasses.dataclass(frozen=True)
class Volume:
    """A volumetric reconstruction: ``data[iy, ix, iz]`` (float32, C-contiguous; the ``(y, x)`` order of a
    grid capture's ``data.reshape(ny, nx, bins)``), and per axis the first voxel centre and the spacing,
    metres."""

    data: np.ndarray
    x: Tuple[float, float]
    y: Tuple[float, float]
    z: Tuple[float, float]

    def centres(self, axis: str) -> np.ndarray:
        """Voxel centres along ``"x"``, ``"y"`` or ``"z"``, metres."""
        if axis not in ("x", "y", "z"):
            raise ValueError(f"axis: {axis!r} is not \"x\", \"y\" or \"z\"")
        first, step = {"x": self.x, "y": self.y, "z": self.z}[axis]
        n = self.data.shape[{"y": 0, "x": 1, "z": 2}[axis]]
        return first + step * np.arange(n)


def _volume(capture: Capture, method: str, snr: Optional[float] = None) -> Volume:
    data, axes = _nlos.volume(capture, method, snr)
    return Volume(data, x=tuple(axes["x"]), y=tuple(axes["y"]), z=tuple(axes["z"]))


def lct(capture: Capture, snr: Optional[float] = None) -> Volume:
    """Light-cone transform (O'Toole et al. 2018) of a confocal capture, prepared as ``nlos reconstruct``
    prepares it (direct light gated)."""
    return _volume(capture, "lct", snr)


def fk(capture: Capture) -> Volume:
    """f-k migration (Lindell et al. 2019) of a confocal capture; see :func:`lct`."""
    return _volume(capture, "fk")


def fbp(capture: Capture) -> Volume:
    """Filtered back-projection of a capture; see :func:`lct`."""
    return _volume(capture, "fbp")


def pf(capture: Capture) -> Volume:
    """Phasor-field reconstruction (Liu et al. 2019) of any capture: confocal, one laser and a sensor grid,
    lasers × sensors, wall points on a grid or in a list; see :func:`lct`."""
    return _volume(capture, "pf")


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
) -> "Reconstruction":
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
    Reconstruction

    Raises
    ------
    ConfigError
        An unknown setting or a value out of range.
    ReconstructError
        The run failed; when it ran to its end but kept almost no surface (the start did not match the
        capture), the exception's ``reconstruction`` holds the :class:`Reconstruction` it made (``out``, when
        given, holds its files too).
    KeyboardInterrupt
        On Ctrl-C, after the current block's checkpoint is written (resume with ``resume=True``).
    """
    try:
        result = _nlos.reconstruct(
            _capture(capture),
            _settings_json(settings),
            None if out is None else os.fspath(out),
            resume,
            progress,
        )
    except ReconstructError as e:
        # A run that kept almost no surface: what it made travels with the exception.
        raw = getattr(e, "result", None)
        if raw is not None:
            e.reconstruction = _reconstruction(raw)
        raise
    return _reconstruction(result)


def read_run(out: Union[str, "os.PathLike[str]"]) -> "Reconstruction":
    """The run recorded in run directory ``out`` (by :func:`reconstruct` or ``nlos reconstruct --out``): its
    surface, reflectance, scale and log as its last finished block left them, read from its checkpoint.
    ``stop`` is ``None`` while the run has blocks left (continue it with ``reconstruct(..., resume=True)``).
    Raises :class:`ReconstructError` for a directory without a record, or one written by another version of
    nlos (saying both versions)."""
    return _reconstruction(_nlos.read_run(os.fspath(out)))


def _reconstruction(result: Dict[str, Any]) -> "Reconstruction":
    return Reconstruction(
        vertices=result["vertices"],
        faces=result["faces"],
        reflectance=json.loads(result["reflectance"]),
        scale=float(result["scale"]),
        albedo=result["albedo"],
        stop=json.loads(result["stop"]),
        notes=list(result["notes"]),
        log=json.loads(result["log"]),
        fit=result["fit"],
        explained=result["explained"],
        support=result["support"],
    )


@dataclasses.dataclass(frozen=True)
class Reconstruction:
    """The outcome of :func:`reconstruct`."""

    #: (n, 3) float32 vertex positions, metres.
    vertices: np.ndarray
    #: (m, 3) uint32 vertex indices, each face facing the wall.
    faces: np.ndarray
    #: The fitted BRDF: its model's name holding its parameters, as settings and checkpoints write it, e.g.
    #: ``{"lambert": {"albedo": 1.0}}``.
    reflectance: Dict[str, Any]
    #: The measurement's scale against the rendering (solved in closed form).
    scale: float
    #: (n,) float32 relative albedo of each vertex (area mean 1; ``mesh.ply``'s ``albedo``), or ``None`` for a
    #: run with one albedo (``albedo = "off"``).
    albedo: Optional[np.ndarray]
    #: Why the run ended: ``"max_stages"``, ``"face_limit"``, ``"time_budget"`` or ``"interrupted"``
    #: (``None`` from :func:`read_run` while the run has blocks left).
    stop: Optional[str]
    #: What the pipeline decided from the capture (gate, last return, sensor fit).
    notes: List[str]
    #: The run log (every iteration's loss, the stages' edge lengths, pruning and residual records).
    log: Dict[str, Any]
    #: How much of its capture the surface explains, in words ("explains 93 % of the light above the
    #: noise (…)"); ``None`` while the run has blocks left.
    fit: Optional[str] = None
    #: The share of the light above the noise floor the surface explains, in [0, 1] (``None`` while the
    #: run has blocks left, or for a capture with nothing above its floor).
    explained: Optional[float] = None
    #: (n,) float32 support of each vertex in [-1, 1] (``mesh.ply``'s ``support``): how much of their light the
    #: data confirm, +1 all of it, -1 none (the area-weighted mean over the faces around); ``None`` while the
    #: run has blocks left.
    support: Optional[np.ndarray] = None

    @property
    def mesh(self) -> Mesh:
        """``(vertices, faces)``, as :func:`evaluate` and :func:`write_mesh` take it."""
        return self.vertices, self.faces


@dataclasses.dataclass(frozen=True)
class Metrics:
    """The metrics of ``nlos eval`` (lengths in metres, angles in degrees): on a ``grid`` x ``grid`` +z ray
    grid over ``x_range`` x ``y_range`` of the wall, the coverage (share of the truth's pixels the
    reconstruction hits), the coverage within ``coverage_threshold`` of the truth's depth, depth errors
    (``_interior``: pixels at least 3 px inside the truth's silhouette); Chamfer and Hausdorff distances;
    the normal error (``_near``: over the vertices within 1 cm of the truth; ``far_vertex_fraction``: the
    share farther away, the rims that hang back along the line of sight)."""

    grid: int
    x_range: Tuple[float, float]
    y_range: Tuple[float, float]
    gt_pixels: int
    reconstruction_pixels: int
    both_pixels: int
    coverage: float
    coverage_within: float
    coverage_threshold: float
    depth_error_mean: float
    depth_error_median: float
    depth_error_rms: float
    depth_error_max: float
    interior_pixels: int
    depth_error_mean_interior: float
    depth_error_mean_silhouette: float
    chamfer: float
    mean_reconstruction_to_gt: float
    mean_gt_to_reconstruction: float
    hausdorff: float
    normal_error_mean_deg: float
    normal_error_rms_deg: float
    normal_error_near_deg: Optional[float]
    far_vertex_fraction: Optional[float]


def evaluate(
    mesh: Union[Mesh, PathLike, Reconstruction],
    gt: Union[Mesh, PathLike],
    grid: int = 128,
    *,
    capture: Optional[Capture] = None,
    x_range: Optional[Tuple[float, float]] = None,
    y_range: Optional[Tuple[float, float]] = None,
) -> Metrics:
    """The metrics of ``nlos eval`` for ``mesh`` against the ground truth ``gt`` (paths, ``(vertices,
    faces)`` pairs, or a :class:`Reconstruction`).

    The ray grid covers the wall rectangle of ``capture``'s scan points (from one outermost point to the
    other), or ``x_range`` x ``y_range`` (metres), or by default [-0.25, 0.25]^2 m.
    """
    if isinstance(mesh, Reconstruction):
        mesh = mesh.mesh
    if capture is not None:
        if x_range is not None or y_range is not None:
            raise ValueError("capture: give the capture or x_range/y_range, not both")
        points = capture.scan_points
        x_range = (float(points[:, 0].min()), float(points[:, 0].max()))
        y_range = (float(points[:, 1].min()), float(points[:, 1].max()))
    values = json.loads(_nlos.evaluate(mesh, gt, grid, x_range, y_range))
    values["x_range"], values["y_range"] = tuple(values["x_range"]), tuple(values["y_range"])
    return Metrics(**values)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """The ``nlos`` command line, in this process (``pip install`` puts it on the PATH as ``nlos``)."""
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    return _nlos.cli(args)
