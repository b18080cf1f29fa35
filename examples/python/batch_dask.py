"""Reconstruct several captures on a Dask cluster: each capture is one task that runs ``nlos.reconstruct``
in a worker, with its own run directory (so a task that dies can be resumed, by Dask's retries or by hand).

    python examples/python/batch_dask.py OUT CAPTURE [CAPTURE ...]

Without a scheduler address in ``DASK_SCHEDULER`` the script starts a ``LocalCluster`` on this machine
(one single-threaded worker process per core); on a cluster, point ``DASK_SCHEDULER`` at its scheduler
(``dask.distributed``'s own deployment tools start it: SSH, Kubernetes, HPC job queues). nlos itself adds no
scheduler: a run is a deterministic function of its capture and settings, so the same capture gives the
same mesh on any worker as one by one.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, Dict, List, Sequence

import nlos


def reconstruct_one(capture: str, out: str, settings: Dict[str, Any]) -> nlos.Reconstruction:
    """One task: the reconstruction of ``capture`` in the run directory ``out`` (resumed when it holds an
    unfinished run's checkpoint)."""
    resume = (Path(out) / "checkpoint.json").is_file()
    return nlos.reconstruct(capture, out, resume=resume, **({} if resume else settings))


def reconstruct_many(client: Any, captures: Sequence[str], out: str, **settings: Any) -> List[nlos.Reconstruction]:
    """Reconstructs every capture as one task of ``client`` (a ``dask.distributed.Client``), each in
    ``out/<capture's file name without extension>``; returns the results in the order of ``captures``."""
    dirs = [str(Path(out) / Path(c).stem) for c in captures]
    if len(set(dirs)) != len(dirs):
        raise ValueError("captures: two captures share a file name, so their run directories would collide")
    futures = client.map(reconstruct_one, list(map(str, captures)), dirs, settings=settings, pure=False)
    return client.gather(futures)


def main(argv: Sequence[str]) -> int:
    from dask.distributed import Client, LocalCluster

    if len(argv) < 2:
        print(__doc__)
        return 2
    out, captures = argv[0], argv[1:]
    address = os.environ.get("DASK_SCHEDULER")
    cluster = None if address else LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1)
    with Client(address or cluster) as client:
        for capture, result in zip(captures, reconstruct_many(client, captures, out)):
            print(f"{capture}: {len(result.faces)} faces, stop: {result.stop}")
    if cluster is not None:
        cluster.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
