"""The renderer as a PyTorch layer: the forward pass renders, the backward pass is the renderer's exact
adjoint (Proposition 1 of Tsai et al. 2019), so a mesh's vertices can be fitted inside any PyTorch
optimisation.

Gradients flow to the vertices; the faces, the setup and the reflectance are fixed per layer. Tensors are
float32 on the CPU (others are converted); the rendering shares its memory with NumPy (no copy).

Example
-------
>>> layer = nlos.torch.RenderLayer(faces, setup)          # doctest: +SKIP
>>> v = torch.tensor(start_vertices, requires_grad=True)  # doctest: +SKIP
>>> loss = ((layer(v) - measured) ** 2).sum()             # doctest: +SKIP
>>> loss.backward()                                       # doctest: +SKIP
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from . import Capture, Renderer

__all__ = ["RenderLayer", "render"]


class _Render(torch.autograd.Function):
    """I = render(V): forward by the renderer, backward by its adjoint at the same vertices."""

    @staticmethod
    def forward(ctx: Any, vertices: torch.Tensor, renderer: Renderer) -> torch.Tensor:  # type: ignore[override]
        v = vertices.detach().to(dtype=torch.float32, device="cpu").contiguous().numpy()
        renderer.set_vertices(v)
        ctx.renderer = renderer
        ctx.vertices = v
        ctx.dtype = vertices.dtype
        ctx.device = vertices.device
        return torch.from_numpy(renderer.forward()).to(device=vertices.device)

    @staticmethod
    def backward(ctx: Any, grad_output: torch.Tensor) -> Any:  # type: ignore[override]
        renderer: Renderer = ctx.renderer
        # The renderer may have moved since (another forward): the adjoint is taken where the forward was.
        renderer.set_vertices(ctx.vertices)
        g = grad_output.detach().to(dtype=torch.float32, device="cpu").contiguous().numpy()
        d_vertices, _ = renderer.adjoint(np.ascontiguousarray(g))
        return torch.from_numpy(d_vertices).to(dtype=ctx.dtype, device=ctx.device), None


class RenderLayer(torch.nn.Module):
    """A rendering layer for one mesh connectivity and one setup: ``layer(vertices)`` is the transient
    (measurements x bins), differentiable with respect to ``vertices`` (n, 3).

    The renderer (and its visibility cache) is built once, from the first vertices seen; keyword
    arguments are those of :class:`nlos.Renderer` (``brdf``, ``albedo``, ``alpha``, ``kernel``,
    ``sampling``, ``visibility``, ...).
    """

    def __init__(self, faces: Any, setup: Capture, **renderer_options: Any) -> None:
        super().__init__()
        self.faces = np.ascontiguousarray(np.asarray(faces, dtype=np.int64))
        self.setup = setup
        self.options = renderer_options
        self.renderer: Renderer | None = None

    def forward(self, vertices: torch.Tensor) -> torch.Tensor:
        if self.renderer is None:
            v = vertices.detach().to(dtype=torch.float32, device="cpu").numpy()
            self.renderer = Renderer(v, self.faces, self.setup, **self.options)
        return _Render.apply(vertices, self.renderer)


def render(vertices: torch.Tensor, faces: Any, setup: Capture, **renderer_options: Any) -> torch.Tensor:
    """Renders ``vertices`` (n, 3) with ``faces`` for ``setup``, differentiably (one renderer per call;
    use :class:`RenderLayer` to keep it across iterations)."""
    return RenderLayer(faces, setup, **renderer_options)(vertices)
