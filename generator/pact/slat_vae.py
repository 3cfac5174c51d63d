"""Structured-latent VAE (PAct stage 2's SLAT, after TRELLIS): local geometry + colour of
each token voxel <-> an 8-dim latent per voxel, decoded finer than the voxel grid.

Tokens are the shell voxels of a part's R = 32 occupancy (``slat_data``). Each carries
64 truncated SDF values on its 4 x 4 x 4 sub-grid and one RGB colour.

A sparse 3x3x3 convolution is emulated by neighbour gathering: for every token the
26 neighbours (plus itself) are looked up in a dense index grid of its part; a neighbour
is a token (its features are gathered), an interior voxel of the part (occupied, no token,
"deep inside") or empty. Each of the 27 slots contributes its features and a one-hot
state (empty / interior / token).

  encoder: per-voxel projection (64 SDF + 3 RGB -> ``embed``), gather 27 neighbours,
           MLP -> mean and log-variance of the 8-dim latent.
  decoder: the voxel's latent + the 27 neighbourhood states (``decoder_context="states"``,
           the small config: each voxel decodes on its own, so training decodes a random
           subset of voxels per step) or the 27 neighbours' latents and states
           ("latents"), MLP -> 64 SDF (tanh, truncated units) + RGB (in [-1, 1]).

Latent statistics (per-channel mean and std over the training set) are buffers, saved
with the weights; the stage-2 flow works on normalized latents (``normalize`` /
``denormalize``). ``decode_part_mesh`` assembles the fine SDF grid (R * 4 = 128, only
around the part's voxels) and runs marching cubes (scikit-image), colouring vertices
with the decoded RGB of their nearest token voxel.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from .model_configs import register
from .slat_data import RESOLUTION, SUB

log = logging.getLogger(__name__)

EMPTY, INTERIOR, TOKEN = 0, 1, 2
_OFFSETS = torch.tensor(
    [[dx, dy, dz] for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)]
)  # (27, 3), index 13 is the voxel itself


@dataclass
class SlatVAEConfig:
    resolution: int = RESOLUTION  # R
    sub: int = SUB  # sub-samples per voxel side; SDF values per voxel = sub^3
    latent_channels: int = 8
    embed: int = 16  # per-voxel projection before gathering (encoder)
    hidden: int = 128
    enc_layers: int = 2
    dec_layers: int = 3
    # "states": the decoder sees its own latent + the 26 neighbours' states (empty /
    # interior / token), so voxels decode independently; "latents": + neighbours' latents
    decoder_context: str = "states"


@dataclass
class SlatVAETrainConfig:
    lr: float = 1e-3
    kl_weight: float = 1e-4
    rgb_weight: float = 1.0
    near_weight: float = 4.0  # extra SDF weight where |target| < 1 (near the surface)
    objects_per_batch: int = 4
    voxels_per_batch: int = 4096  # decoded targets per step (0: every voxel)
    bf16: bool = True


class SparseParts(NamedTuple):
    """A batch of parts' token voxels, flattened.

    coords (N, 3) long voxel indices, group (N,) long part index in the batch,
    neighbours (N, 27) long: token index of each 3x3x3 neighbour or -1,
    states (N, 27) long: EMPTY / INTERIOR / TOKEN.
    """

    coords: torch.Tensor
    group: torch.Tensor
    neighbours: torch.Tensor
    states: torch.Tensor


def sparse_parts(
    coords: torch.Tensor, group: torch.Tensor, occupancy: torch.Tensor | None = None
) -> SparseParts:
    """Neighbour tables of token voxels.

    coords (N, 3) long, group (N,) long in [0, G), occupancy (G, R, R, R) bool or None
    (None: no interior voxels, every non-token neighbour is empty).
    """
    R = RESOLUTION
    G = int(group.max()) + 1 if len(group) else 0
    dense = torch.full((G, R + 2, R + 2, R + 2), -1, dtype=torch.long)  # (G, R+2, R+2, R+2)
    if occupancy is not None:
        dense[:, 1:-1, 1:-1, 1:-1] = torch.where(occupancy[:G].bool(), -2, -1)
    c = coords.long() + 1
    dense[group, c[:, 0], c[:, 1], c[:, 2]] = torch.arange(len(coords))
    nb = c[:, None, :] + _OFFSETS[None]  # (N, 27, 3)
    look = dense[group[:, None], nb[..., 0], nb[..., 1], nb[..., 2]]  # (N, 27)
    states = torch.where(look >= 0, TOKEN, torch.where(look == -2, INTERIOR, EMPTY))
    return SparseParts(coords.long(), group.long(), look.clamp(min=-1), states)


def gather(x: torch.Tensor, sp: SparseParts) -> torch.Tensor:
    """(N, C) per-token features -> (N, 27 * (C + 3)) neighbourhood features with states."""
    pad = torch.cat([x, x.new_zeros(1, x.shape[1])], dim=0)  # row N is "no token"
    idx = torch.where(sp.neighbours >= 0, sp.neighbours, len(x))  # (N, 27)
    feats = pad[idx]  # (N, 27, C)
    onehot = F.one_hot(sp.states, 3).to(x.dtype)  # (N, 27, 3)
    return torch.cat([feats, onehot], dim=-1).flatten(1)


def _subset(sp: SparseParts, rows: torch.Tensor) -> SparseParts:
    """The rows ``rows`` of a SparseParts (neighbour indices still point into all tokens)."""
    return SparseParts(sp.coords[rows], sp.group[rows], sp.neighbours[rows], sp.states[rows])


def _mlp(dims: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i in range(len(dims) - 1):
        layers.append(nn.Linear(dims[i], dims[i + 1]))
        if i < len(dims) - 2:
            layers.append(nn.SiLU())
    return nn.Sequential(*layers)


class SlatOutput(NamedTuple):
    sdf: torch.Tensor  # (N, sub^3) truncated units, in [-1, 1]
    rgb: torch.Tensor  # (N, 3) in [-1, 1]
    mean: torch.Tensor  # (N, C)
    logvar: torch.Tensor  # (N, C)


@register("slat_vae", SlatVAEConfig)
class SlatVAE(nn.Module):
    def __init__(self, cfg: SlatVAEConfig) -> None:
        super().__init__()
        self.cfg = cfg
        n_sdf, C, H = cfg.sub**3, cfg.latent_channels, cfg.hidden
        self.in_proj = nn.Linear(n_sdf + 3, cfg.embed)
        self.encoder = _mlp([27 * (cfg.embed + 3)] + [H] * cfg.enc_layers + [2 * C])
        if cfg.decoder_context not in ("states", "latents"):
            raise ValueError(
                f"decoder_context must be 'states' or 'latents', not {cfg.decoder_context!r}"
            )
        dec_in = C + 27 * 3 if cfg.decoder_context == "states" else 27 * (C + 3)
        self.decoder = _mlp([dec_in] + [H] * cfg.dec_layers + [n_sdf + 3])
        self.register_buffer("latent_mean", torch.zeros(C))
        self.register_buffer("latent_std", torch.ones(C))

    def encode(
        self,
        sdf: torch.Tensor,
        rgb: torch.Tensor,
        sp: SparseParts,
        rows: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """sdf (N, sub^3) in [-1, 1], rgb (N, 3) in [-1, 1] -> mean, logvar (N, C), or
        (Q, C) for the token rows ``rows`` (Q,) only."""
        h = F.silu(self.in_proj(torch.cat([sdf, rgb], dim=-1)))  # (N, embed)
        g = gather(h, sp if rows is None else _subset(sp, rows))  # (N or Q, 27 (embed + 3))
        mean, logvar = self.encoder(g).chunk(2, dim=-1)
        return mean, logvar.clamp(-12.0, 6.0)

    def decode(self, z: torch.Tensor, sp: SparseParts) -> tuple[torch.Tensor, torch.Tensor]:
        """z (N, C) raw latents of the rows of ``sp`` -> sdf (N, sub^3), rgb (N, 3) in [-1, 1]."""
        if self.cfg.decoder_context == "states":
            ctx = torch.cat([z, F.one_hot(sp.states, 3).to(z.dtype).flatten(1)], dim=-1)
        else:
            ctx = gather(z, sp)
        out = self.decoder(ctx)  # (N, sub^3 + 3)
        return torch.tanh(out[:, :-3]), torch.tanh(out[:, -3:])

    def forward(
        self,
        sdf: torch.Tensor,
        rgb: torch.Tensor,
        sp: SparseParts,
        sample: bool = True,
        rows: torch.Tensor | None = None,
    ) -> SlatOutput:
        """Reconstruct every token, or only ``rows`` (needs decoder_context "states")."""
        mean, logvar = self.encode(sdf, rgb, sp, rows)
        z = mean + torch.randn_like(mean) * (0.5 * logvar).exp() if sample else mean
        if rows is not None and self.cfg.decoder_context != "states":
            raise ValueError("decoding a subset of rows needs decoder_context='states'")
        s, c = self.decode(z, sp if rows is None else _subset(sp, rows))
        return SlatOutput(s, c, mean, logvar)

    def normalize(self, z: torch.Tensor) -> torch.Tensor:
        return (z - self.latent_mean) / self.latent_std

    def denormalize(self, z: torch.Tensor) -> torch.Tensor:
        return z * self.latent_std + self.latent_mean


def vae_loss(
    out: SlatOutput, sdf: torch.Tensor, rgb: torch.Tensor, cfg: SlatVAETrainConfig
) -> tuple[torch.Tensor, dict[str, float]]:
    """L1 on the truncated SDF (weighted near the surface) + L1 on RGB + KL."""
    w = 1.0 + cfg.near_weight * (sdf.abs() < 0.999).float()  # (N, sub^3)
    l_sdf = (w * (out.sdf.float() - sdf).abs()).sum() / w.sum()
    l_rgb = (out.rgb.float() - rgb).abs().mean()
    mean, logvar = out.mean.float(), out.logvar.float()
    kl = 0.5 * (mean.pow(2) + logvar.exp() - 1.0 - logvar).mean()
    loss = l_sdf + cfg.rgb_weight * l_rgb + cfg.kl_weight * kl
    return loss, {
        "loss": loss.item(),
        "sdf_l1": l_sdf.item(),
        "rgb_l1": l_rgb.item(),
        "kl": kl.item(),
    }


# --------------------------------------------------------------------------- meshes


def fine_sdf_grid(
    coords: np.ndarray, sdf: np.ndarray, occupancy: np.ndarray, margin: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Assemble one part's fine SDF grid around its voxels.

    coords (N, 3) token voxel indices, sdf (N, sub^3) truncated units, occupancy (R, R, R)
    bool (interior voxels = occupied and not tokens). Returns (grid (X, Y, Z) float32,
    origin (3,) int fine index of grid[0, 0, 0]). Empty space is +1, interior -1.
    """
    R, s = occupancy.shape[0], round(sdf.shape[1] ** (1 / 3))
    occ_idx = np.argwhere(occupancy)
    every = np.concatenate([occ_idx, coords.astype(np.int64)]) if len(occ_idx) else coords
    lo = np.maximum(every.min(0) - margin, 0)
    hi = np.minimum(every.max(0) + 1 + margin, R)
    shape = tuple((hi - lo) * s)
    grid = np.ones(shape, np.float32)
    inside = occupancy[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
    interior = np.repeat(np.repeat(np.repeat(inside, s, 0), s, 1), s, 2)
    grid[interior] = -1.0
    blocks = sdf.reshape(-1, s, s, s)
    rel = (coords.astype(np.int64) - lo) * s  # (N, 3)
    a = np.arange(s)
    ix = rel[:, 0, None, None, None] + a[None, :, None, None]
    iy = rel[:, 1, None, None, None] + a[None, None, :, None]
    iz = rel[:, 2, None, None, None] + a[None, None, None, :]
    grid[ix, iy, iz] = blocks
    return grid, lo * s


def decode_part_mesh(
    coords: np.ndarray, sdf: np.ndarray, rgb: np.ndarray, occupancy: np.ndarray
):  # -> trimesh.Trimesh | None
    """Marching cubes over a part's decoded fine SDF; vertex colours from decoded RGB.

    coords (N, 3), sdf (N, sub^3) truncated units, rgb (N, 3) uint8, occupancy (R, R, R).
    Returns a trimesh.Trimesh in the normalized frame, or None if no surface is found.
    """
    import trimesh
    from scipy import ndimage
    from skimage.measure import marching_cubes

    if len(coords) == 0:
        return None
    R = occupancy.shape[0]
    fine = R * round(sdf.shape[1] ** (1 / 3))
    grid, origin = fine_sdf_grid(coords, sdf, occupancy)
    grid = np.pad(grid, 1, constant_values=1.0)  # close surfaces at the crop border
    if grid.min() >= 0 or grid.max() <= 0:
        return None
    verts, faces, _, _ = marching_cubes(grid, level=0.0)
    verts = -0.5 + (verts - 1 + origin + 0.5) / fine  # fine index -> normalized frame
    # nearest token voxel's colour for every vertex
    token = np.zeros((R, R, R), bool)
    token[coords[:, 0], coords[:, 1], coords[:, 2]] = True
    colour = np.zeros((R, R, R, 3), np.uint8)
    colour[coords[:, 0], coords[:, 1], coords[:, 2]] = rgb
    _, (nx, ny, nz) = ndimage.distance_transform_edt(~token, return_indices=True)
    v = np.clip(np.floor((verts + 0.5) * R).astype(np.int64), 0, R - 1)
    vi = (
        nx[v[:, 0], v[:, 1], v[:, 2]],
        ny[v[:, 0], v[:, 1], v[:, 2]],
        nz[v[:, 0], v[:, 1], v[:, 2]],
    )
    vc = np.concatenate([colour[vi], np.full((len(v), 1), 255, np.uint8)], axis=1)
    # marching_cubes on a "positive outside" field gives inward normals: flip the faces
    mesh = trimesh.Trimesh(verts, faces[:, ::-1], vertex_colors=vc, process=False)
    return mesh


@torch.no_grad()
def decode_latents(
    vae: SlatVAE, coords: torch.Tensor, z: torch.Tensor, occupancy: torch.Tensor
) -> tuple[np.ndarray, np.ndarray]:
    """Decode one part: coords (N, 3), normalized latents z (N, C), occupancy (R, R, R)
    -> sdf (N, sub^3) float32 and rgb (N, 3) uint8."""
    group = torch.zeros(len(coords), dtype=torch.long)
    sp = sparse_parts(coords.long().cpu(), group, occupancy[None].cpu())
    dev = next(vae.parameters()).device
    sp = SparseParts(*(t.to(dev) for t in sp))
    sdf, rgb = vae.decode(vae.denormalize(z.to(dev).float()), sp)
    rgb8 = ((rgb.float().cpu().numpy() + 1.0) * 127.5).round().clip(0, 255).astype(np.uint8)
    return sdf.float().cpu().numpy(), rgb8
