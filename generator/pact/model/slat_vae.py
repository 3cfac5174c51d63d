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
around the part's voxels), lets the stage-1 occupancy fix its topology
(``constrain_sdf``: a lattice through every occupied voxel forced inside, islands and
cavities removed, so a part decodes to one closed piece per connected piece of its
occupancy, thin panels included) and runs marching cubes (scikit-image), colouring
vertices with the decoded RGB of their nearest token voxel.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from scipy import ndimage

from generator.pact.model.model_configs import register

log = logging.getLogger(__name__)

RESOLUTION = 32  # R, voxel grid of the dataset occupancy
SUB = 4  # sub-samples per voxel side

EMPTY, INTERIOR, TOKEN = 0, 1, 2
_OFFSETS = torch.tensor(
    [[dx, dy, dz] for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)]
)  # (27, 3), index 13 is the voxel itself


def shell_voxels(occ: np.ndarray) -> np.ndarray:
    """(R, R, R) bool: occupied voxels with an unoccupied voxel among their 26 neighbours."""
    inner = ndimage.binary_erosion(occ, structure=np.ones((3, 3, 3), bool), border_value=0)
    return occ & ~inner


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


#: Value (truncated units: 1 = one voxel = ``sub`` fine cells) written into a forced
#: inside cell, and the largest value left next to one: half a fine cell each way, so a
#: forced sheet one fine cell thick decodes to a plate about one fine cell thick.
FORCED = 0.125
#: Side (fine cells) of the closing that fills the lattice's net into sheets: anchors of
#: neighbouring voxels lie up to 2 SUB - 1 cells apart, so a smaller closing (5 did)
#: leaves holes in a wall wherever stage 2 decoded no surface
LATTICE_CLOSING = 2 * SUB + 1
#: The 13 "positive" of the 26 neighbour offsets (each neighbouring pair once).
_HALF_OFFSETS = np.array([d for d in itertools.product((-1, 0, 1), repeat=3) if d > (0, 0, 0)])
_FACES = ndimage.generate_binary_structure(3, 1)  # 6-connectivity


def _crop_box(coords: np.ndarray, occupancy: np.ndarray, margin: int = 1):
    """(lo, hi) voxel box of a part's occupancy and tokens, grown by ``margin``."""
    R = occupancy.shape[0]
    occ_idx = np.argwhere(occupancy)
    every = np.concatenate([occ_idx, coords.astype(np.int64)]) if len(occ_idx) else coords
    lo = np.maximum(every.min(0) - margin, 0)
    hi = np.minimum(every.max(0) + 1 + margin, R)
    return lo.astype(np.int64), hi.astype(np.int64)


def _anchors(grid: np.ndarray, s: int) -> np.ndarray:
    """Per voxel of the crop its anchor: the fine cell (crop index) of its block where the
    decoded SDF is lowest (deepest inside stage 2's surface; ties and flat blocks go to
    the cells nearest the block centre). (nx, ny, nz, 3) int."""
    n = np.array(grid.shape) // s
    blocks = grid.reshape(n[0], s, n[1], s, n[2], s).transpose(0, 2, 4, 1, 3, 5)
    blocks = blocks.reshape(*n, s**3)
    a = np.arange(s) - (s - 1) / 2
    off = np.stack(np.meshgrid(a, a, a, indexing="ij"), -1).reshape(-1, 3)
    idx = np.argmin(blocks + 0.05 * np.linalg.norm(off, axis=1), axis=-1)
    sub = np.stack(np.unravel_index(idx, (s, s, s)), -1)
    return np.moveaxis(np.indices(tuple(n)), 0, -1) * s + sub


def occupancy_lattice(grid: np.ndarray, occ: np.ndarray, s: int) -> np.ndarray:
    """Fine cells (bool, the grid's shape) of the lattice that ties a part's voxels
    together: every occupied voxel's anchor (``_anchors``) and a 6-connected digital
    line from it to the anchor of each of its 26 occupied neighbours. The lattice of
    one 26-connected piece of ``occ`` is one 6-connected set of fine cells; it stays
    within the occupied voxels except where a diagonal line cuts a corner (at most one
    voxel out)."""
    anchors = _anchors(grid, s)
    out = np.zeros(grid.shape, bool)
    vox = np.argwhere(occ)
    if len(vox) == 0:
        return out
    a = anchors[tuple(vox.T)]
    out[tuple(a.T)] = True
    steps = 2 * s  # anchors of neighbours are < 2 s cells apart per axis: unit steps
    t = np.arange(steps + 1) / steps
    for d in _HALF_OFFSETS:
        w = vox + d
        ok = (w >= 0).all(1) & (w < np.array(occ.shape)).all(1)
        v, w = vox[ok], w[ok]
        ok = occ[tuple(w.T)]
        if not ok.any():
            continue
        p, q = anchors[tuple(v[ok].T)], anchors[tuple(w[ok].T)]  # (M, 3)
        pts = np.rint(p[:, None] + (q - p)[:, None] * t[None, :, None]).astype(np.int64)
        step = pts[:, 1:] - pts[:, :-1]  # (M, steps, 3) in {-1, 0, 1}
        base = pts[:, :-1]
        for corner in (base + step * [1, 0, 0], base + step * [1, 1, 0]):
            out[tuple(corner.reshape(-1, 3).T)] = True
        out[tuple(pts.reshape(-1, 3).T)] = True
    return out


def constrain_sdf(
    grid: np.ndarray, occ: np.ndarray, interior: np.ndarray, s: int
) -> tuple[np.ndarray, np.ndarray]:
    """Stage 2's fine SDF with its topology fixed by the stage-1 occupancy.

    grid (X, Y, Z) fine SDF of a crop (``fine_sdf_grid``: tokens decoded, interior -1,
    empty +1), occ / interior (X/s, Y/s, Z/s) bool, the crop's occupied and interior
    voxels. Returns (grid, forced) where forced marks the cells forced inside:

    1. the lattice (``occupancy_lattice``) of the occupancy, closed (a cube of
       ``LATTICE_CLOSING`` fine cells) within the occupied voxels: a sheet through the
       anchors of a thin panel, solid in thick parts. Where stage 2 already has its surface, the anchors lie
       inside it and nothing changes; where it decoded nothing (a thin wall's voxel
       with no negative value), the sheet stands in for it;
    2. forced cells get at most -FORCED, their positive neighbours at most +FORCED
       (a forced sheet decodes about one fine cell thick);
    3. inside regions (6-connected) that touch no forced or interior cell are islands:
       set outside;
    4. outside regions (6-connected) that do not reach the crop's border are cavities:
       set inside.

    The inside set is then one 6-connected region per 26-connected piece of the
    occupancy with a connected complement, so marching cubes gives one closed surface
    per piece. Cells outside the occupancy are never made inside except along the
    lattice's diagonal lines (at most one voxel out); nothing stage 2 put inside a
    kept region moves.
    """
    fine_occ = np.repeat(np.repeat(np.repeat(occ, s, 0), s, 1), s, 2)
    fine_int = np.repeat(np.repeat(np.repeat(interior, s, 0), s, 1), s, 2)
    lattice = occupancy_lattice(grid, occ, s)
    grown = ndimage.maximum_filter(lattice, size=LATTICE_CLOSING, mode="constant", cval=False)
    closed = ndimage.minimum_filter(grown, size=LATTICE_CLOSING, mode="constant", cval=True)
    forced = lattice | (closed & fine_occ)
    g = grid.astype(np.float32, copy=True)
    g[forced] = np.minimum(g[forced], -FORCED)
    near = ndimage.binary_dilation(forced, _FACES) & ~forced
    g[near] = np.minimum(g[near], FORCED)
    g[g == 0] = 1e-6  # no sample exactly on the level set (degenerate triangles)
    inside = g < 0
    labels, n = ndimage.label(inside, _FACES)
    if n:
        keep = np.zeros(n + 1, bool)
        keep[np.unique(labels[forced | fine_int])] = True
        keep[0] = False
        island = inside & ~keep[labels]
        g[island] = FORCED
    outside = np.pad(g >= 0, 1, constant_values=True)
    labels, n = ndimage.label(outside, _FACES)
    cavity = (labels != labels[0, 0, 0])[1:-1, 1:-1, 1:-1] & (g >= 0)
    g[cavity] = -FORCED
    return g, forced


def _vertex_colours(verts: np.ndarray, coords: np.ndarray, rgb: np.ndarray, R: int) -> np.ndarray:
    """(V, 4) uint8: every vertex takes the decoded RGB of its nearest token voxel."""
    token = _token_grid(coords, R)
    colour = np.zeros((R, R, R, 3), np.uint8)
    colour[coords[:, 0], coords[:, 1], coords[:, 2]] = rgb
    _, (nx, ny, nz) = ndimage.distance_transform_edt(~token, return_indices=True)
    v = np.clip(np.floor((verts + 0.5) * R).astype(np.int64), 0, R - 1)
    vi = (
        nx[v[:, 0], v[:, 1], v[:, 2]],
        ny[v[:, 0], v[:, 1], v[:, 2]],
        nz[v[:, 0], v[:, 1], v[:, 2]],
    )
    return np.concatenate([colour[vi], np.full((len(v), 1), 255, np.uint8)], axis=1)


def _closed_pieces(mesh) -> bool:  # noqa: ANN001
    """Every connected piece of ``mesh`` is watertight, consistently wound, positive."""
    from generator.mesh_repair.cleaning import piece_report

    _, volumes, closed = piece_report(mesh)
    return bool(closed and len(volumes) and np.all(volumes > 0))


def _surface(grid: np.ndarray, origin: np.ndarray, fine: int):  # -> trimesh.Trimesh | None
    """Marching cubes of a fine SDF crop (padded with "outside") in the normalized frame,
    outward-wound (earlier versions flipped the faces and made every part inside out)."""
    import trimesh
    from skimage.measure import marching_cubes

    grid = np.pad(grid, 1, constant_values=1.0)  # close surfaces at the crop border
    if grid.min() >= 0 or grid.max() <= 0:
        return None
    verts, faces, _, _ = marching_cubes(grid, level=0.0)
    verts = -0.5 + (verts - 1 + origin + 0.5) / fine  # fine index -> normalized frame
    # scikit-image winds the faces of a "negative inside" field outward (positive volume)
    return trimesh.Trimesh(verts, faces, process=False)


def occupancy_mesh(occupancy: np.ndarray, sub: int = SUB):  # -> trimesh.Trimesh | None
    """The fallback surface: marching cubes of the occupancy itself on the fine grid
    (one closed surface per 6-connected piece), no colours."""
    coords = np.argwhere(occupancy)
    if len(coords) == 0:
        return None
    lo, hi = _crop_box(coords, occupancy)
    occ = occupancy[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
    fine = np.repeat(np.repeat(np.repeat(occ, sub, 0), sub, 1), sub, 2)
    return _surface(
        np.where(fine, -0.5, 0.5).astype(np.float32), lo * sub, occupancy.shape[0] * sub
    )


def decode_part_mesh(
    coords: np.ndarray,
    sdf: np.ndarray,
    rgb: np.ndarray,
    occupancy: np.ndarray,
    constrain: bool = True,
):  # -> trimesh.Trimesh | None
    """Marching cubes over a part's decoded fine SDF; vertex colours from decoded RGB.

    coords (N, 3), sdf (N, sub^3) truncated units, rgb (N, 3) uint8, occupancy (R, R, R).
    With ``constrain`` (the default) the stage-1 occupancy fixes the topology
    (``constrain_sdf``): one closed, outward-wound surface per 26-connected piece of the
    occupancy, no islands, no cavities; when that fails (not closed), the occupancy's
    own surface (``occupancy_mesh``) is used. ``constrain=False``: the raw decoded SDF
    (islands, fragments), as before. Returns a trimesh.Trimesh in the normalized frame,
    or None if no surface is found.
    """
    if len(coords) == 0:
        return None
    R = occupancy.shape[0]
    s = round(sdf.shape[1] ** (1 / 3))
    fine = R * s
    grid, origin = fine_sdf_grid(coords, sdf, occupancy)
    if constrain:
        token = _token_grid(coords, R)
        box = tuple(
            slice(a, a + n) for a, n in zip(origin // s, np.array(grid.shape) // s, strict=True)
        )
        occ, tok = occupancy[box], token[box]
        grid, _ = constrain_sdf(grid, occ | tok, occ & ~tok, s)
    mesh = _surface(grid, origin, fine)
    if constrain and (mesh is None or not _closed_pieces(mesh)):
        log.warning("constrained decoding gave no closed surface; meshing the occupancy")
        mesh = occupancy_mesh(occupancy | token, s)
    if mesh is None:
        return None
    mesh.visual.vertex_colors = _vertex_colours(mesh.vertices, coords, rgb, R)
    return mesh


def _token_grid(coords: np.ndarray, R: int) -> np.ndarray:
    token = np.zeros((R, R, R), bool)
    token[coords[:, 0], coords[:, 1], coords[:, 2]] = True
    return token


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
