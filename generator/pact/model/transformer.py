"""Transformer pieces shared by the image encoder and the part-aware flow transformer.

Attention runs through ``F.scaled_dot_product_attention``; the fused ``qkv`` projection
uses the (3, heads, head_dim) output layout of DINOv2 so its weights load unchanged.
"""

from __future__ import annotations

import math

import torch
import torch.nn as nn
import torch.nn.functional as F


class RMSNorm(nn.Module):
    """Per-head RMS norm for queries and keys (TRELLIS ``qk_rms_norm``)."""

    def __init__(self, dim: int, eps: float = 1e-6) -> None:
        super().__init__()
        self.eps = eps
        self.weight = nn.Parameter(torch.ones(dim))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x32 = x.float()
        x32 = x32 * torch.rsqrt(x32.pow(2).mean(-1, keepdim=True) + self.eps)
        return (x32 * self.weight.float()).to(x.dtype)


class SelfAttention(nn.Module):
    def __init__(self, dim: int, heads: int, qk_norm: bool = False, bias: bool = True) -> None:
        super().__init__()
        if dim % heads:
            raise ValueError(f"width {dim} is not divisible by {heads} heads")
        self.heads = heads
        self.qkv = nn.Linear(dim, 3 * dim, bias=bias)
        self.out = nn.Linear(dim, dim, bias=bias)
        self.q_norm = RMSNorm(dim // heads) if qk_norm else nn.Identity()
        self.k_norm = RMSNorm(dim // heads) if qk_norm else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        B, N, D = x.shape  # (B, N, D)
        qkv = self.qkv(x).view(B, N, 3, self.heads, D // self.heads)  # (B, N, 3, H, hd)
        q, k, v = qkv.permute(2, 0, 3, 1, 4).unbind(0)  # each (B, H, N, hd)
        q, k = self.q_norm(q), self.k_norm(k)
        y = F.scaled_dot_product_attention(q, k, v)  # (B, H, N, hd)
        return self.out(y.transpose(1, 2).reshape(B, N, D))


class CrossAttention(nn.Module):
    """Queries from the tokens (width ``dim``), keys/values from a context of width ``ctx_dim``."""

    def __init__(self, dim: int, ctx_dim: int, heads: int, qk_norm: bool = False) -> None:
        super().__init__()
        if dim % heads:
            raise ValueError(f"width {dim} is not divisible by {heads} heads")
        self.heads = heads
        self.q = nn.Linear(dim, dim)
        self.kv = nn.Linear(ctx_dim, 2 * dim)
        self.out = nn.Linear(dim, dim)
        self.q_norm = RMSNorm(dim // heads) if qk_norm else nn.Identity()
        self.k_norm = RMSNorm(dim // heads) if qk_norm else nn.Identity()

    def forward(self, x: torch.Tensor, ctx: torch.Tensor) -> torch.Tensor:
        B, N, D = x.shape  # (B, N, D)
        M = ctx.shape[1]  # ctx (B, M, D_ctx)
        hd = D // self.heads
        q = self.q(x).view(B, N, self.heads, hd).transpose(1, 2)  # (B, H, N, hd)
        kv = self.kv(ctx).view(B, M, 2, self.heads, hd)  # (B, M, 2, H, hd)
        k, v = kv.permute(2, 0, 3, 1, 4).unbind(0)  # each (B, H, M, hd)
        q, k = self.q_norm(q), self.k_norm(k)
        y = F.scaled_dot_product_attention(q, k, v)  # (B, H, N, hd)
        return self.out(y.transpose(1, 2).reshape(B, N, D))


class MLP(nn.Module):
    def __init__(self, dim: int, hidden: int, approximate: str = "none") -> None:
        super().__init__()
        self.fc1 = nn.Linear(dim, hidden)
        self.act = nn.GELU(approximate=approximate)
        self.fc2 = nn.Linear(hidden, dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc2(self.act(self.fc1(x)))


def timestep_embedding(t: torch.Tensor, dim: int, max_period: float = 10000.0) -> torch.Tensor:
    """Sinusoidal features of a (B,) float tensor -> (B, dim)."""
    half = dim // 2
    freqs = torch.exp(
        -math.log(max_period) * torch.arange(half, dtype=torch.float32, device=t.device) / half
    )  # (half,)
    args = t.float()[:, None] * freqs[None]  # (B, half)
    emb = torch.cat([torch.cos(args), torch.sin(args)], dim=-1)
    if dim % 2:
        emb = F.pad(emb, (0, 1))
    return emb  # (B, dim)


class TimestepEmbedder(nn.Module):
    """t in [0, 1] -> (B, D); t is scaled by 1000 before the sinusoids, as in TRELLIS/DiT."""

    def __init__(self, dim: int, freq_dim: int = 256) -> None:
        super().__init__()
        self.freq_dim = freq_dim
        self.mlp = nn.Sequential(nn.Linear(freq_dim, dim), nn.SiLU(), nn.Linear(dim, dim))

    def forward(self, t: torch.Tensor) -> torch.Tensor:
        return self.mlp(timestep_embedding(t * 1000.0, self.freq_dim))  # (B, D)


def sincos_3d(grid: int, dim: int) -> torch.Tensor:
    """Fixed 3D sinusoidal position code for a grid^3 lattice in [x, y, z] raster order.

    Returns (grid^3, dim): each axis gets dim // 3 channels (rounded down to even),
    the rest are zero.
    """
    per_axis = (dim // 3) // 2 * 2
    half = per_axis // 2
    freqs = 1.0 / (10000.0 ** (torch.arange(half, dtype=torch.float64) / max(half, 1)))  # (half,)
    coords = torch.stack(
        torch.meshgrid(*(torch.arange(grid, dtype=torch.float64),) * 3, indexing="ij"), dim=-1
    ).reshape(-1, 3)  # (L, 3)
    parts = []
    for a in range(3):
        args = coords[:, a : a + 1] * freqs[None]  # (L, half)
        parts += [torch.sin(args), torch.cos(args)]
    pe = torch.cat(parts, dim=-1)  # (L, 3 * per_axis)
    pe = F.pad(pe, (0, dim - pe.shape[1]))
    return pe.float()  # (L, dim)


def init_adaln_transformer(model: nn.Module, zero: tuple[nn.Linear, ...]) -> None:
    """TRELLIS/DiT initialization of a flow transformer with ``t_embed``, ``blocks``
    (each with an ``adaLN`` head) and the output layers ``zero``: Xavier-uniform linears
    with zero biases, N(0, 0.02) timestep MLP, adaLN-Zero (every block starts as the
    identity) and zeroed output layers (the model starts by predicting 0)."""
    for m in model.modules():
        if isinstance(m, nn.Linear):
            nn.init.xavier_uniform_(m.weight)
            nn.init.zeros_(m.bias)
    nn.init.normal_(model.t_embed.mlp[0].weight, std=0.02)
    nn.init.normal_(model.t_embed.mlp[2].weight, std=0.02)
    for block in model.blocks:
        nn.init.zeros_(block.adaLN[-1].weight)
        nn.init.zeros_(block.adaLN[-1].bias)
    for lin in zero:
        nn.init.zeros_(lin.weight)
        nn.init.zeros_(lin.bias)


PREDICTIONS = ("velocity", "x0")


def check_prediction(predict: str) -> None:
    """Raise ValueError unless ``predict`` names a flow output parameterization."""
    if predict not in PREDICTIONS:
        raise ValueError(f"predict must be one of {PREDICTIONS}, got {predict!r}")


def output_to_velocity(
    out: torch.Tensor, x_t: torch.Tensor, t: torch.Tensor, predict: str, t_min: float
) -> torch.Tensor:
    """A flow network's raw output -> the rectified-flow velocity v = eps - x_0.

    ``predict == "velocity"``: the output is v. ``"x0"`` (the only other value,
    ``check_prediction``): the output is x0_hat, and with
    x_t = (1 - t) x_0 + t eps the velocity it implies is (x_t - x0_hat) / t (t floored at
    ``t_min``). t (B,) broadcasts over the trailing dims of ``out``.
    """
    if predict == "velocity":
        return out
    tt = t.clamp_min(t_min).view(-1, *([1] * (out.dim() - 1))).to(out.dtype)
    return (x_t.to(out.dtype) - out) / tt
