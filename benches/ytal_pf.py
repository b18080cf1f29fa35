"""Our phasor-field volume against y-tal's (`tal.reconstruct.pf_dev`) on the same one-laser capture.

    pip install y-tal numpy
    cargo build --release -p nlos-cli
    python benches/ytal_pf.py [CAPTURE.json] [--planes N]

CAPTURE defaults to the shared `reference/bunny_single_mc.json` (one laser, 64 x 64 sensors, 1200 bins of
1.2 mm). Both reconstruct the same virtual wave (our `nlos_init::pf` defaults: wavelength 3 sensor spacings,
2 periods within +-3 sigma, which is y-tal's `wl_sigma = pi * periods * wavelength / 18`) on the sensor grid's
columns. y-tal computes N depth planes over the object's range (default 8: 64 x 64 x 64 ran out of 23 GB on a
2-core, 24 GB machine); ours computes the full depth (every bin's depth, 1200 planes) and is compared on the
same planes. Printed: the time and peak memory of each (ours: `nlos init --method pf` as a child process,
reading the file included), and, over the columns where both find the object (column maximum above half of
each volume's largest), the depth of each column's maximum: how often they agree within one plane, and the
mean difference.
"""

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("NLOS_SHARED_DATA", ROOT.parent / "shared" / "data"))
NLOS = os.environ.get("NLOS_BIN", str(ROOT / "target" / "release" / "nlos"))
WAVELENGTH_PER_SPACING, PERIODS = 3.0, 2.0


def ours(capture: Path, work: Path):
    """Our volume (ny, nx, nz) with its depth axis, wall seconds and peak resident memory (bytes)."""
    npy = work / "pf.npy"
    t0 = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    subprocess.run(
        [NLOS, "init", str(capture), "--method", "pf", "--gate", "off", "--depth-step", "0.0006",
         "--out", str(work / "pf.obj"), "--volume", str(npy)],
        check=True, capture_output=True,
    )
    wall = time.perf_counter() - t0
    peak = max(before, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss) * 1024
    vol = np.load(npy)
    nz = vol.shape[2]
    return vol, 0.0003 + 0.0006 * np.arange(nz), wall, peak


def theirs(capture: Path, work: Path, depths: np.ndarray):
    """y-tal's volume (nx, ny, len(depths)), wall seconds and peak resident memory (bytes)."""
    import tal

    tal_file = work / "capture.hdf5"
    subprocess.run([NLOS, "convert", str(capture), str(tal_file)], check=True, capture_output=True)
    data = tal.io.read_capture(str(tal_file))
    spacing = float(np.abs(data.sensor_grid_xyz[1, 0, 0] - data.sensor_grid_xyz[0, 0, 0]))
    wavelength = WAVELENGTH_PER_SPACING * spacing
    volume = tal.reconstruct.get_volume_project_rw(data, depths=list(depths))
    t0 = time.perf_counter()
    out = tal.reconstruct.pf_dev.solve(
        data, wl_mean=wavelength, wl_sigma=np.pi * PERIODS * wavelength / 18, volume_xyz=volume,
        volume_format=tal.enums.VolumeFormat.X_Y_Z_3, camera_system=tal.enums.CameraSystem.DIRECT_LIGHT,
        progress=False, nt=data.H.shape[0], try_optimize_convolutions=False,  # y-tal 0.20: see the module doc
    )
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return np.abs(np.asarray(out)).reshape(volume.shape[:3]), wall, peak


def main():
    args = sys.argv[1:]
    planes = 8
    if "--planes" in args:
        i = args.index("--planes")
        planes = int(args[i + 1])
        del args[i : i + 2]
    capture = Path(args[0]) if args else SHARED / "reference" / "bunny_single_mc.json"
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        vol, z, our_s, our_mem = ours(capture, work)
        # The object's depth range from our volume: where the brightest columns peak.
        col_max = vol.max(axis=2)
        bright = col_max > 0.5 * col_max.max()
        peak_z = z[vol.argmax(axis=2)][bright]
        depths = np.linspace(np.percentile(peak_z, 2) - 0.01, np.percentile(peak_z, 98) + 0.01, planes)
        ytal, ytal_s, ytal_mem = theirs(capture, work, depths)
    # Ours on y-tal's planes (nearest of our depths), both as [x, y, plane].
    ours_on = vol[:, :, np.abs(z[None, :] - depths[:, None]).argmin(axis=1)].transpose(1, 0, 2)
    both = (ours_on.max(axis=2) > 0.5 * ours_on.max()) & (ytal.max(axis=2) > 0.5 * ytal.max())
    i_ours, i_ytal = ours_on.argmax(axis=2)[both], ytal.argmax(axis=2)[both]
    step = depths[1] - depths[0] if planes > 1 else 0.0
    result = {
        "capture": capture.name,
        "ours": {"volume": list(vol.shape), "seconds": round(our_s, 2), "peak_memory_mb": round(our_mem / 2**20)},
        "y-tal pf_dev": {"volume": list(ytal.shape), "seconds": round(ytal_s, 2),
                         "peak_memory_mb": round(ytal_mem / 2**20)},
        "planes_m": [round(d, 4) for d in depths],
        "columns_compared": int(both.sum()),
        "same_plane_or_neighbour": float(np.mean(np.abs(i_ours - i_ytal) <= 1)),
        "mean_depth_difference_mm": float(np.mean((i_ours - i_ytal) * step) * 1e3),
        "mean_abs_depth_difference_mm": float(np.mean(np.abs(i_ours - i_ytal) * step) * 1e3),
    }
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
