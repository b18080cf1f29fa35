"""Fit a mesh's vertices to a capture with PyTorch, the nlos renderer as a layer.

    python examples/python/fit_mesh_torch.py CAPTURE [STEPS]

CAPTURE is any capture nlos reads (default: the built-in fixture). The start is the LCT surface
`nlos reconstruct` would begin from; Adam moves its vertices to lower the L2 misfit between the rendering
(scaled in closed form, as the capture's units are arbitrary) and the capture.
"""

import sys
from pathlib import Path

import numpy as np
import torch

import nlos
import nlos.torch


def fit(capture_path, steps=30, lr=1e-3):
    capture = nlos.load(capture_path)
    vertices, faces = nlos.initial_surface(capture)
    measured = torch.from_numpy(capture.data)
    layer = nlos.torch.RenderLayer(faces, capture)
    v = torch.tensor(vertices, requires_grad=True)
    optimiser = torch.optim.Adam([v], lr=lr)
    losses = []
    for _ in range(steps):
        optimiser.zero_grad()
        rendered = layer(v)
        scale = (rendered * measured).sum() / (rendered * rendered).sum()  # closed-form intensity scale
        loss = 0.5 * ((scale.detach() * rendered - measured) ** 2).sum() / (measured**2).sum()
        loss.backward()
        optimiser.step()
        losses.append(loss.item())
    return v.detach().numpy(), faces, losses


if __name__ == "__main__":
    default = Path(__file__).resolve().parents[2] / "fixtures" / "builtin" / "capture.hdf5"
    path = sys.argv[1] if len(sys.argv) > 1 else default
    steps = int(sys.argv[2]) if len(sys.argv) > 2 else 30
    v, f, losses = fit(path, steps)
    print(f"loss {losses[0]:.4e} -> {losses[-1]:.4e} over {len(losses)} Adam steps; {len(f)} faces")
    nlos.write_mesh("fitted.obj", v, f)
