"""The cost of calling the renderer from Python: `nlos.Renderer.forward()` on the 10k-face bunny at the
seed's setup, in the configuration of the Rust benchmark `cargo bench --bench render -- bunny10k/forward`
(every 7th face of the shared bunny, confocal 64 x 64, 1200 bins of 1.2 mm, tent kernel, fixed(1),
visibility cached at level 1). Prints the median of N calls; compare with the criterion median.

    python crates/nlos-py/bench/forward_overhead.py [N]
"""

import os
import statistics
import sys
import time
from pathlib import Path

import nlos

root = Path(os.environ.get("NLOS_SHARED_DATA", Path(__file__).resolve().parents[4] / "shared" / "data"))
v, f = nlos.read_mesh(root / "meshes" / "bunny_centered.obj")
f = f[::7]
setup = nlos.confocal_setup()
r = nlos.Renderer(v, f, setup, kernel="tent", sampling="fixed", visibility="cached", vis_level=1)
r.forward()  # warm up
n = int(sys.argv[1]) if len(sys.argv) > 1 else 20
times = []
for _ in range(n):
    t = time.perf_counter()
    out = r.forward()
    times.append(time.perf_counter() - t)
print(f"{len(f)} faces, {out.shape}: forward median {statistics.median(times) * 1e3:.1f} ms over {n} calls "
      f"(min {min(times) * 1e3:.1f}, max {max(times) * 1e3:.1f})")
