"""The renderer as a PyTorch layer: the forward pass renders, the backward pass is the renderer's exact
adjoint (Proposition 1 of Tsai et al. 2019), so a mesh's vertices can be fitted inside any PyTorch
optimisation.

Gradients flow to the vertices; the faces and the setup are fixed per layer, the reflectance is set on
its renderer. Tensors are
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

    The renderer is built once, from the first vertices seen; keyword arguments are those of
    :class:`nlos.Renderer` (``brdf``, ``albedo``, ``alpha``, ``kernel``, ``sampling``, ``visibility``,
    ``device``, ...).
    Its visibility cache (which triangle sees which wall spot) is recomputed whenever a vertex has moved
    more than ``refresh`` times the mesh's mean edge length since it was last computed (``None``: never,
    as the reconstruction loop keeps it within a block). The reflectance is ``layer.renderer.reflectance``;
    set it with ``layer.renderer.set_reflectance`` (the adjoint's gradients name the same parameters).
    """

    def __init__(self, faces: Any, setup: Capture, *, refresh: float | None = 0.5, **renderer_options: Any) -> None:
        super().__init__()
        if refresh is not None and not refresh > 0:
            raise ValueError(f"refresh: {refresh!r} must be a positive fraction of an edge, or None")
        self.faces = np.ascontiguousarray(np.asarray(faces, dtype=np.int64))
        self.setup = setup
        self.options = renderer_options
        self.refresh = refresh
        self.renderer: Renderer | None = None
        #: The vertices at which the visibility cache was last computed.
        self.visibility_at: np.ndarray | None = None
        self._edge = 0.0

    def forward(self, vertices: torch.Tensor) -> torch.Tensor:
        v = vertices.detach().to(dtype=torch.float32, device="cpu").contiguous().numpy()
        if self.renderer is None:
            self.renderer = Renderer(v, self.faces, self.setup, **self.options)
            self.visibility_at = v.copy()
            corners = v[self.faces]
            self._edge = float(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).mean())
        elif self.refresh is not None and self.visibility_at is not None:
            moved = float(np.sqrt(((v - self.visibility_at) ** 2).sum(axis=1).max(initial=0.0)))
            if moved > self.refresh * self._edge:
                self.renderer.set_vertices(v)
                self.renderer.refresh_visibility()
                self.visibility_at = v.copy()
        return _Render.apply(vertices, self.renderer)


def render(vertices: torch.Tensor, faces: Any, setup: Capture, **renderer_options: Any) -> torch.Tensor:
    """Renders ``vertices`` (n, 3) with ``faces`` for ``setup``, differentiably (one renderer per call;
    use :class:`RenderLayer` to keep it across iterations)."""
    return RenderLayer(faces, setup, **renderer_options)(vertices)
