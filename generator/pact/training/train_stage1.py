"""Train PAct stage 1: the sparse-structure VAE, then the part-aware flow model.

Read top to bottom: ``Args``, the helpers (distributed, schedule, checkpoints, logs),
``train_vae``, ``train_flow``, ``train_stage1``.

    python -m generator.pact.training.train_stage1 --data runs/data/train --out runs/pact/stage1 --part vae
    torchrun --nproc_per_node 2 -m generator.pact.training.train_stage1 --data ... --out ... --part flow

VAE: every used part slot of every training object is one sample (the occupancy grid of
that part), plus a few all-empty grids per batch so that the empty-slot latent decodes to
nothing. Loss ``ss_vae.vae_loss`` (BCE + dice + KL).

Flow: the VAE is frozen; each object's part latents (posterior means; unused slots get
the empty-grid latent) are computed once and cached in memory, normalised per channel.
One sample is (object, random view): the image encoder (trained jointly, same optimiser)
encodes the view, the GT part mask conditions (with the dropout of ``flow.flow_loss``).

Both: AdamW, linear warm-up then cosine (or constant) LR, optional bf16 autocast (the
config's ``bf16``), gradient clipping, a checkpoint every ``ckpt_every`` steps (a folder
written under a temporary name and renamed) holding the model(s) and ``state.pt``
(optimiser, step, RNG), exact resume, losses to ``log.csv`` and TensorBoard (``tb/``).

Randomness is keyed by (seed, step, rank): each step reseeds its own generators, so a
resumed run draws exactly what an uninterrupted run would have drawn.

Data parallel: under ``torchrun`` (WORLD_SIZE > 1) the process group is initialised
(gloo on CPU, nccl on CUDA); every rank draws the same global batch indices and takes
its own slice (the DistributedSampler split), gradients are all-reduced (averaged) before
clipping, so the ranks' weights stay identical; only rank 0 writes files.
"""

from __future__ import annotations

import argparse
import copy
import csv
import hashlib
import json
import logging
import math
import os
import shutil
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.distributed as dist
import torch.nn as nn
import torch.nn.functional as F

from generator.pact.model.checkpoint import check_output_dir, load_checkpoint, save_checkpoint
from generator.pact.model.flow import flow_loss
from generator.pact.model.ss_vae import SparseStructureVAE, vae_loss
from generator.pact.model.stage1 import (
    LatentStats,
    Stage1Config,
    build_stage1,
    load_config,
    load_stage1,
    save_stage1,
)
from generator.pact.training.augment import AugmentConfig, augment_inputs
from generator.pact.training.stage1_data import Stage1Dataset

log = logging.getLogger(__name__)


@dataclass
class Args:
    data_dir: str = "runs/data/train"  # dataset folder (pact dataset build)
    out_dir: str = "runs/pact/stage1"  # run folder: vae/ and flow/ (checkpoint/, log.csv, tb/)
    config: str = "small"  # packaged config name or path to a JSON
    part: str = "all"  # "vae", "flow" or "all" (VAE, then flow)
    steps: int | None = None  # overrides vae_steps / flow_steps for the part(s) trained
    vae_steps: int = 1500  # VAE optimiser steps (the schedule's length)
    flow_steps: int = 3000  # flow optimiser steps (the schedule's length)
    batch_size: int | None = None  # per rank; None: the config's vae_train / flow_train
    lr: float | None = None  # peak learning rate; None: the config's
    warmup: int = 100  # linear warm-up, in steps
    schedule: str = "cosine"  # "cosine" (to min_lr_frac * lr) or "constant"
    min_lr_frac: float = 0.1  # the cosine's floor, as a fraction of lr
    weight_decay: float = 0.0  # AdamW weight decay
    grad_clip: float = 1.0  # gradient-norm clip
    bf16: bool | None = None  # bf16 autocast; None: the config's
    empty_fraction: float = 0.0625  # VAE: share of each batch that is an all-empty grid
    val_fraction: float = 0.05  # objects held out by id hash (see data.py)
    val_items: int = 32  # flow: fixed validation batch size
    log_every: int = 10  # steps between log rows
    eval_every: int = 250  # steps between validations
    ckpt_every: int = 200  # steps between checkpoints
    snapshot_every: int | None = None  # flow: also keep flow/snapshots/step_<k>/stage1 (curves)
    seed: int = 0  # every random draw is keyed by (seed, step, rank)
    resume: bool = True  # continue from the run's last checkpoint when there is one
    threads: int | None = None  # torch intra-op threads per rank (None: torch's default)
    max_minutes: float | None = None  # stop (with a checkpoint) after this many minutes
    stop_after: int | None = None  # stop (with a checkpoint) at this step; resume later
    limit_objects: int | None = None  # use only the first N objects (tests)
    vae_dir: str | None = None  # frozen VAE for the flow; None: <out>/vae/checkpoint/ss_vae
    init_from: str | None = None  # flow, new run: start from this stage-1 folder's weights
    # flow: input augmentation (generator/pact/training/augment.py), probabilities per sample
    aug_recolor: float = 0.0  # a random tint per part
    aug_photometric: float = 0.0  # brightness, contrast, saturation
    aug_rgb_dropout: float = 0.0  # the object one flat colour: only silhouette and mask left
    aug_mask_noise: float = 0.0  # ragged mask edges, as a SAM-style mask has
    write_shipped_weights: bool = False  # allow out_dir inside generator/pact/weights/


# --- distributed ----------------------------------------------------------------------


@dataclass
class Dist:
    rank: int = 0
    world: int = 1
    device: torch.device = torch.device("cpu")

    @property
    def main(self) -> bool:
        return self.rank == 0


def setup_distributed() -> Dist:
    """Join the process group when launched by torchrun (WORLD_SIZE > 1)."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    cuda = torch.cuda.is_available()
    if world > 1 and not dist.is_initialized():
        dist.init_process_group(backend="nccl" if cuda else "gloo")
    rank = dist.get_rank() if dist.is_initialized() else 0
    world = dist.get_world_size() if dist.is_initialized() else 1
    if cuda:
        local = int(os.environ.get("LOCAL_RANK", "0"))
        torch.cuda.set_device(local)
        device = torch.device("cuda", local)
    else:
        device = torch.device("cpu")
    return Dist(rank, world, device)


def optimizer_step(
    opt: torch.optim.Optimizer,
    loss: torch.Tensor,
    params: list[nn.Parameter],
    world: int,
    clip: float,
) -> float:
    """Backward, average gradients across ranks, clip, step; returns the gradient norm."""
    opt.zero_grad(set_to_none=True)
    loss.backward()
    average_gradients(params, world)
    grad_norm = float(nn.utils.clip_grad_norm_(params, clip))
    opt.step()
    return grad_norm


def average_gradients(params: list[nn.Parameter], world: int) -> None:
    """All-reduce (mean) the gradients of ``params`` in one flat buffer."""
    if world == 1:
        return
    grads = [p.grad if p.grad is not None else torch.zeros_like(p) for p in params]
    flat = torch.cat([g.reshape(-1) for g in grads])
    dist.all_reduce(flat)
    flat /= world
    offset = 0
    for p, g in zip(params, grads, strict=True):
        n = g.numel()
        p.grad = flat[offset : offset + n].view_as(p).clone()
        offset += n


def barrier(d: Dist) -> None:
    if d.world > 1:
        dist.barrier()


# --- schedule, randomness ---------------------------------------------------------------


def lr_at(step: int, base: float, args: Args, total: int) -> float:
    """Linear warm-up over ``args.warmup`` steps, then constant or cosine decay."""
    if step < args.warmup:
        return base * (step + 1) / args.warmup
    if args.schedule == "constant":
        return base
    progress = min(1.0, (step - args.warmup) / max(1, total - args.warmup))
    return base * (
        args.min_lr_frac + (1 - args.min_lr_frac) * 0.5 * (1 + math.cos(math.pi * progress))
    )


def step_generator(seed: int, step: int, stream: int, rank: int = 0) -> torch.Generator:
    """A generator keyed by (seed, step, stream, rank): stateless, so resume is exact."""
    return torch.Generator().manual_seed(((seed * 1_000_003 + step) * 97 + stream) * 131 + rank)


# --- checkpoints and logs ---------------------------------------------------------------


def save_training_checkpoint(
    folder: Path, models: dict[str, Any], optimizer: torch.optim.Optimizer, step: int
) -> None:
    """``folder`` = ``<part dir>/checkpoint``; written as ``checkpoint.tmp`` then swapped in.

    ``models`` maps a sub-folder name to a callable writing it (so the VAE and the stage-1
    pair use their own formats)."""
    tmp, old = folder.with_name("checkpoint.tmp"), folder.with_name("checkpoint.old")
    for p in (tmp, old):
        if p.exists():
            shutil.rmtree(p)
    tmp.mkdir(parents=True)
    for name, write in models.items():
        write(tmp / name)
    state = {"step": step, "optimizer": optimizer.state_dict(), "torch_rng": torch.get_rng_state()}
    torch.save(state, tmp / "state.pt")
    if folder.exists():
        folder.rename(old)
    tmp.rename(folder)
    if old.exists():
        shutil.rmtree(old)


def find_checkpoint(part_dir: Path) -> Path | None:
    for name in ("checkpoint", "checkpoint.old"):  # .old: interrupted between the renames
        if (part_dir / name / "state.pt").is_file():
            return part_dir / name
    return None


class RunLog:
    """CSV + TensorBoard scalars, rank 0 only. On resume, rows after ``start`` are dropped."""

    def __init__(self, part_dir: Path, enabled: bool, start: int) -> None:
        self.enabled = enabled
        self.csv_path = part_dir / "log.csv"
        self.writer = None
        if not enabled:
            return
        from torch.utils.tensorboard import SummaryWriter

        part_dir.mkdir(parents=True, exist_ok=True)
        rows: list[dict[str, str]] = []
        if start > 0 and self.csv_path.is_file():
            with self.csv_path.open() as f:
                rows = [r for r in csv.DictReader(f) if int(r["step"]) <= start]
        self.rows = rows
        self._rewrite()
        self.writer = SummaryWriter(str(part_dir / "tb"), purge_step=start if start else None)

    def _rewrite(self) -> None:
        keys: list[str] = []
        for r in self.rows:
            keys += [k for k in r if k not in keys]
        tmp = self.csv_path.with_suffix(".csv.tmp")
        with tmp.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=keys or ["step"])
            w.writeheader()
            w.writerows(self.rows)
        tmp.replace(self.csv_path)

    def write(self, step: int, scalars: dict[str, float], prefix: str) -> None:
        if not self.enabled:
            return
        for k, v in scalars.items():
            self.writer.add_scalar(f"{prefix}/{k}", v, step)
        row = {"step": str(step), **{f"{prefix}/{k}": f"{v:.6g}" for k, v in scalars.items()}}
        self.rows.append(row)
        if set(row) - set(self.rows[0]) or len(self.rows) == 1:
            self._rewrite()  # a new column: rewrite with the wider header
        else:
            with self.csv_path.open("a", newline="") as f:
                csv.DictWriter(f, fieldnames=list(self.rows[0])).writerow(row)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.flush()
            self.writer.close()


def _autocast(device: torch.device, enabled: bool):
    return torch.autocast(device.type, dtype=torch.bfloat16, enabled=enabled)


def _optimizer(params: list[nn.Parameter], lr: float, args: Args) -> torch.optim.AdamW:
    return torch.optim.AdamW(params, lr=lr, betas=(0.9, 0.99), weight_decay=args.weight_decay)


def _resume(
    part_dir: Path, args: Args, optimizer: torch.optim.Optimizer
) -> tuple[int, Path | None]:
    ckpt = find_checkpoint(part_dir) if args.resume else None
    if ckpt is None:
        return 0, None
    state = torch.load(ckpt / "state.pt", map_location="cpu", weights_only=False)
    optimizer.load_state_dict(state["optimizer"])
    torch.set_rng_state(state["torch_rng"])
    log.info("resuming %s at step %d", ckpt, state["step"])
    return int(state["step"]), ckpt


def _should_stop(t0: float, step: int, args: Args, d: Dist) -> bool:
    over = args.max_minutes is not None and time.time() - t0 > 60 * args.max_minutes
    over = over or (args.stop_after is not None and step >= args.stop_after)
    if d.world > 1:  # every rank must agree, or the all-reduce deadlocks
        flag = torch.tensor([float(over)])
        dist.all_reduce(flag)
        over = bool(flag.item() > 0)
    return over


# --- VAE --------------------------------------------------------------------------------


@torch.no_grad()
def evaluate_vae(vae: SparseStructureVAE, ds: Stage1Dataset, batch: int = 32) -> dict[str, float]:
    """Reconstruction of every used part slot of ``ds`` (posterior mean, logits > 0):
    ``iou`` over all voxels pooled, ``part_iou`` the mean of per-part IoUs, and whether
    the empty grid decodes to nothing (``empty_voxels``)."""
    was = vae.training
    vae.eval()
    device = next(vae.parameters()).device
    slots = ds.part_slots()
    inter = union = 0
    part_ious = []
    for i in range(0, len(slots), batch):
        grids = np.stack([ds.part_grid(int(o), int(s)) for o, s in slots[i : i + batch]])
        occ = torch.from_numpy(grids).to(device)[:, None].float()  # (N, 1, R, R, R)
        pred = vae.decode(vae.encode(occ)[1]) > 0
        gt = occ > 0.5
        it = (pred & gt).flatten(1).sum(1)
        un = (pred | gt).flatten(1).sum(1)
        inter += int(it.sum())
        union += int(un.sum())
        part_ious += (it.float() / un.clamp_min(1).float()).tolist()
    R = ds.resolution
    empty = vae.decode(vae.encode(torch.zeros(1, 1, R, R, R, device=device))[1]) > 0
    vae.train(was)
    return {
        "iou": inter / max(1, union),
        "part_iou": float(np.mean(part_ious)),
        "empty_voxels": float(empty.sum()),
    }


def train_vae(args: Args, cfg: Stage1Config, d: Dist) -> tuple[Path, dict[str, nn.Module]]:
    """Train the sparse-structure VAE; returns the checkpoint folder and the model."""
    part_dir = Path(args.out_dir) / "vae"
    tcfg = cfg.vae_train
    B = args.batch_size or tcfg.batch_size
    lr = args.lr or tcfg.lr
    bf16 = tcfg.bf16 if args.bf16 is None else args.bf16
    total = args.steps or args.vae_steps
    T = cfg.flow.max_parts

    train_ds = Stage1Dataset(args.data_dir, T, "train", args.val_fraction, limit=args.limit_objects)
    val_ds = Stage1Dataset(args.data_dir, T, "val", args.val_fraction, limit=args.limit_objects)
    slots = train_ds.part_slots()  # (P, 2)
    R = train_ds.resolution
    if R != cfg.vae.resolution:
        raise ValueError(f"dataset resolution {R} != config vae.resolution {cfg.vae.resolution}")

    torch.manual_seed(args.seed)
    vae = build_stage1(cfg)["vae"].to(d.device)
    opt = _optimizer(list(vae.parameters()), lr, args)
    step, ckpt = _resume(part_dir, args, opt)
    if ckpt is not None:
        vae.load_state_dict(load_checkpoint(ckpt / "ss_vae").state_dict())
    params = list(vae.parameters())
    logs = RunLog(part_dir, d.main, step)
    n_empty = int(round(args.empty_fraction * B))
    log.info(
        "VAE: %d train parts, %d val objects, batch %d x %d ranks, steps %d -> %d",
        len(slots),
        val_ds.num_objects,
        B,
        d.world,
        step,
        total,
    )

    def checkpoint() -> None:
        if d.main:
            save_training_checkpoint(
                part_dir / "checkpoint",
                {"ss_vae": lambda p: save_checkpoint(vae, p, {"step": step})},
                opt,
                step,
            )
        barrier(d)

    t0 = t_log = time.time()
    vae.train()
    while step < total:
        # the global batch (same on every rank), this rank's slice of it
        pick = torch.randint(
            len(slots), (B * d.world,), generator=step_generator(args.seed, step, 0)
        )
        pick = pick[d.rank * B : (d.rank + 1) * B].numpy()
        grids = np.stack([train_ds.part_grid(int(o), int(s)) for o, s in slots[pick]])
        grids[B - n_empty :] = False  # the empty-slot target
        occ = torch.from_numpy(grids).to(d.device)  # (B, R, R, R)

        for g in opt.param_groups:
            g["lr"] = lr_at(step, lr, args, total)
        with _autocast(d.device, bf16):
            loss, metrics = vae_loss(
                vae, occ, tcfg, generator=step_generator(args.seed, step, 1, d.rank)
            )
        grad_norm = optimizer_step(opt, loss, params, d.world, args.grad_clip)
        step += 1

        if step % args.log_every == 0 or step == total:
            now = time.time()
            rate = args.log_every * B * d.world / max(1e-9, now - t_log)
            t_log = now
            metrics.update(lr=opt.param_groups[0]["lr"], grad_norm=grad_norm, parts_per_s=rate)
            logs.write(step, metrics, "vae")
            log.info(
                "vae step %d loss %.4f iou %.3f kl %.3f (%.1f parts/s)",
                step,
                metrics["loss"],
                metrics["iou"],
                metrics["kl"],
                rate,
            )
        if d.main and (step % args.eval_every == 0 or step == total):
            ev = evaluate_vae(vae, val_ds)
            logs.write(step, ev, "vae_val")
            log.info(
                "vae step %d val iou %.4f part_iou %.4f empty %d",
                step,
                ev["iou"],
                ev["part_iou"],
                ev["empty_voxels"],
            )
        stop = _should_stop(t0, step, args, d)
        if step % args.ckpt_every == 0 or step == total or stop:
            checkpoint()
        if stop:
            log.info("stopping at step %d (max_minutes / stop_after)", step)
            break
    logs.close()
    return part_dir / "checkpoint" / "ss_vae", {"vae": vae}


# --- flow -------------------------------------------------------------------------------


@torch.no_grad()
def latent_cache(
    vae: SparseStructureVAE, ds: Stage1Dataset, batch: int = 64
) -> tuple[torch.Tensor, LatentStats]:
    """Every object's part latents (N, T, C, r, r, r) (posterior means; unused slots hold
    the empty-grid latent) and per-channel statistics of the used slots' latents."""
    vae.eval()
    device = next(vae.parameters()).device
    slots = ds.part_slots()  # (P, 2)
    empty = vae.empty_latent().cpu()  # (C, r, r, r)
    cache = empty.expand(ds.num_objects, ds.max_parts, *empty.shape).clone()
    for i in range(0, len(slots), batch):
        chunk = slots[i : i + batch]
        grids = np.stack([ds.part_grid(int(o), int(s)) for o, s in chunk])
        occ = torch.from_numpy(grids).to(device)[:, None].float()
        mean = vae.encode(occ)[1].cpu()  # (n, C, r, r, r)
        cache[chunk[:, 0], chunk[:, 1]] = mean
    used = cache[slots[:, 0], slots[:, 1]]  # (P, C, r, r, r)
    C = used.shape[1]
    per_c = used.transpose(0, 1).reshape(C, -1)
    stats = LatentStats(tuple(per_c.mean(1).tolist()), tuple(per_c.std(1).clamp_min(1e-3).tolist()))
    return cache, stats


def training_inputs(
    encoder: nn.Module,
    batch: dict[str, torch.Tensor],
    device: torch.device | str,
    jitter: float = 0.0,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """A batch's images and part masks as the encoder takes them (its ``prepare``: with
    ``foreground_crop``, whitened and cropped round the GT foreground, mask != 0)."""
    image, mask = batch["image"].to(device), batch["mask"].to(device)
    return encoder.prepare(image, mask > 0, mask, jitter, generator)


def aux_seg_loss(encoder: nn.Module, tokens: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Soft cross-entropy of the encoder's per-patch part-id logits against each patch's
    histogram of mask ids (ids past the head's classes count as background)."""
    logits = encoder.segment(tokens).float()  # (B, g, g, C)
    C, p = logits.shape[-1], encoder.cfg.patch_size
    ids = torch.where(mask >= C, torch.zeros_like(mask), mask)
    hist = F.avg_pool2d(F.one_hot(ids, C).permute(0, 3, 1, 2).float(), p)  # (B, C, g, g)
    return -(hist.permute(0, 2, 3, 1) * logits.log_softmax(-1)).sum(-1).mean()


def train_flow(args: Args, cfg: Stage1Config, d: Dist) -> tuple[Path, dict[str, nn.Module]]:
    """Train the image encoder + part-aware flow on frozen-VAE latents; returns the
    stage-1 checkpoint folder and the models."""
    part_dir = Path(args.out_dir) / "flow"
    tcfg = cfg.flow_train
    B = args.batch_size or tcfg.batch_size
    lr = args.lr or tcfg.lr
    bf16 = tcfg.bf16 if args.bf16 is None else args.bf16
    total = args.steps or args.flow_steps
    T = cfg.flow.max_parts
    S = cfg.image_encoder.image_size

    vae_dir = Path(args.vae_dir) if args.vae_dir else Path(args.out_dir) / "vae/checkpoint/ss_vae"
    vae = load_checkpoint(vae_dir, d.device).eval()
    for p in vae.parameters():
        p.requires_grad_(False)
    train_ds = Stage1Dataset(args.data_dir, T, "train", args.val_fraction, S, args.limit_objects)
    val_ds = Stage1Dataset(args.data_dir, T, "val", args.val_fraction, S, args.limit_objects)
    # the weights the run starts from (its checkpoint, else --init-from): their latent
    # statistics normalize the latents, as they did when those weights were trained
    ckpt = find_checkpoint(part_dir) if args.resume else None
    start_from = ckpt / "stage1" if ckpt is not None else args.init_from
    start = None
    if start_from is not None:
        start = load_stage1(start_from, d.device)
        for role in ("image_encoder", "flow"):
            if getattr(start[1], role) != getattr(cfg, role):
                raise ValueError(
                    f"{start_from}: its {role} config differs from the training config's "
                    f"({getattr(start[1], role)} vs {getattr(cfg, role)})"
                )
    start_models, start_stats = (start[0], start[2]) if start is not None else (None, None)
    t_cache = time.time()
    cache_file = part_dir / "latent_cache.pt"
    key = {  # what the cached latents depend on
        "vae": hashlib.sha256((vae_dir / "model.safetensors").read_bytes()).hexdigest(),
        "data": str(Path(args.data_dir).resolve()),
        "objects": [train_ds.object_ids, val_ds.object_ids],
        "stats": asdict(start_stats) if start_stats is not None else None,
    }
    saved = torch.load(cache_file, weights_only=False) if cache_file.is_file() else None
    if saved is not None and saved["key"] == key:
        cache, val_cache, stats = saved["train"], saved["val"], LatentStats(**saved["stats"])
    else:
        cache, stats = latent_cache(vae, train_ds)
        if start_stats is not None:
            stats = start_stats
        val_cache, _ = latent_cache(vae, val_ds)
        cache, val_cache = stats.normalize(cache), stats.normalize(val_cache)
        if d.main:  # a cache for resumed runs; written under a temporary name
            part_dir.mkdir(parents=True, exist_ok=True)
            blob = {"key": key, "train": cache, "val": val_cache, "stats": asdict(stats)}
            torch.save(blob, cache_file.with_suffix(".tmp"))
            cache_file.with_suffix(".tmp").replace(cache_file)
    log.info(
        "latent cache: %d + %d objects in %.1fs; std per channel %s",
        len(cache),
        len(val_cache),
        time.time() - t_cache,
        [round(s, 3) for s in stats.std],
    )

    torch.manual_seed(args.seed)
    models = build_stage1(cfg)
    models.pop("vae")
    encoder, flow = models["image_encoder"].to(d.device), models["flow"].to(d.device)
    params = [p for m in (encoder, flow) for p in m.parameters() if p.requires_grad]
    opt = _optimizer(params, lr, args)
    step, _ = _resume(part_dir, args, opt)
    if start_models is not None:
        encoder.load_state_dict(start_models["image_encoder"].state_dict())
        flow.load_state_dict(start_models["flow"].state_dict())
        if ckpt is None:
            log.info("flow: initialized from %s (step 0, fresh optimizer)", args.init_from)
    logs = RunLog(part_dir, d.main, step)
    log.info(
        "flow: %d train objects x %d views, batch %d x %d ranks, steps %d -> %d",
        train_ds.num_objects,
        train_ds.views,
        B,
        d.world,
        step,
        total,
    )

    # a fixed validation batch: (object, view) pairs, t and noise from a fixed seed
    g_val = step_generator(args.seed, 0, 7)
    val_items = torch.randint(len(val_ds), (min(args.val_items, len(val_ds)),), generator=g_val)
    val_batch = val_ds.batch(val_items.tolist())

    def val_loss() -> dict[str, float]:
        encoder.eval(), flow.eval()
        with torch.no_grad(), _autocast(d.device, bf16):
            image, mask = training_inputs(encoder, val_batch, d.device)
            cond = encoder(image)
            x0 = val_cache[val_batch["object"]].to(d.device)
            _, m = flow_loss(
                flow,
                x0,
                cond,
                mask,
                val_batch["exists"].to(d.device),
                tcfg,
                generator=step_generator(args.seed, 0, 8),
            )
        encoder.train(), flow.train()
        return m

    def checkpoint() -> None:
        if d.main:
            save_training_checkpoint(
                part_dir / "checkpoint",
                {
                    "stage1": lambda p: save_stage1(
                        models, cfg, p, stats, extra={"step": step, "vae": str(vae_dir)}
                    )
                },
                opt,
                step,
            )
        barrier(d)

    def snapshot() -> None:
        """The weights at this step, kept beside the rolling checkpoint (a training curve
        scores them: bench/training_curve.py); save_stage1 writes under a temporary name."""
        if d.main:
            extra = {"step": step, "samples_seen": step * B * d.world, "vae": str(vae_dir)}
            save_stage1(
                models, cfg, part_dir / f"snapshots/step_{step:06d}/stage1", stats, extra=extra
            )

    augment = AugmentConfig(
        recolor=args.aug_recolor,
        photometric=args.aug_photometric,
        rgb_dropout=args.aug_rgb_dropout,
        mask_noise=args.aug_mask_noise,
        max_parts=T,
    )
    t0 = t_log = time.time()
    encoder.train(), flow.train()
    while step < total:
        pick = torch.randint(
            len(train_ds), (B * d.world,), generator=step_generator(args.seed, step, 0)
        )
        batch = train_ds.batch(pick[d.rank * B : (d.rank + 1) * B].tolist())
        if augment.active:
            batch["image"], batch["mask"] = augment_inputs(
                batch["image"], batch["mask"], augment, step_generator(args.seed, step, 3, d.rank)
            )
        x0 = cache[batch["object"]].to(d.device)  # (B, T, C, r, r, r)

        for g in opt.param_groups:
            g["lr"] = lr_at(step, lr, args, total)
        image, mask = training_inputs(
            encoder, batch, d.device, tcfg.crop_jitter, step_generator(args.seed, step, 2, d.rank)
        )
        with _autocast(d.device, bf16):
            cond = encoder(image)  # (B, N_img, D_img)
            loss, metrics = flow_loss(
                flow,
                x0,
                cond,
                mask,
                batch["exists"].to(d.device),
                tcfg,
                generator=step_generator(args.seed, step, 1, d.rank),
            )
            if tcfg.aux_seg_weight > 0:
                seg = aux_seg_loss(encoder, cond, mask)
                loss = loss + tcfg.aux_seg_weight * seg
                metrics.update(loss=loss.item(), aux_seg=seg.item())
        grad_norm = optimizer_step(opt, loss, params, d.world, args.grad_clip)
        step += 1

        if step % args.log_every == 0 or step == total:
            now = time.time()
            rate = args.log_every * B * d.world / max(1e-9, now - t_log)
            t_log = now
            metrics.update(lr=opt.param_groups[0]["lr"], grad_norm=grad_norm, samples_per_s=rate)
            logs.write(step, metrics, "flow")
            log.info(
                "flow step %d loss %.4f mse %.4f exists %.4f (%.2f samples/s)",
                step,
                metrics["loss"],
                metrics["mse"],
                metrics["exists_bce"],
                rate,
            )
        if d.main and (step % args.eval_every == 0 or step == total):
            ev = val_loss()
            logs.write(step, ev, "flow_val")
            log.info("flow step %d val loss %.4f mse %.4f", step, ev["loss"], ev["mse"])
        stop = _should_stop(t0, step, args, d)
        if step % args.ckpt_every == 0 or step == total or stop:
            checkpoint()
        if args.snapshot_every and (step % args.snapshot_every == 0 or step == total):
            snapshot()
        if stop:
            log.info("stopping at step %d (max_minutes / stop_after)", step)
            break
    logs.close()
    return part_dir / "checkpoint" / "stage1", models


# --- entry points -----------------------------------------------------------------------


@dataclass
class Stage1Run:
    checkpoints: dict[str, Path] = field(default_factory=dict)  # role -> checkpoint folder
    models: dict[str, nn.Module] = field(default_factory=dict)  # role -> trained module


def train_stage1(
    data_dir: str | Path,
    out_dir: str | Path = "runs/pact/stage1",
    config: str = "small",
    part: str = "all",
    steps: int | None = None,
    resume: bool = True,
    **overrides: Any,
) -> Stage1Run:
    """Train stage 1 (``part`` = "vae", "flow" or "all"). Works alone or under torchrun;
    other ``Args`` fields can be passed as keywords. Returns the checkpoint folders by
    role (``ss_vae``: the VAE, ``stage1``: image encoder + flow) and the trained models."""
    args = Args(
        data_dir=str(data_dir),
        out_dir=str(out_dir),
        config=config,
        part=part,
        steps=steps,
        resume=resume,
        **overrides,
    )
    if args.part not in ("vae", "flow", "all"):
        raise ValueError(f"part must be 'vae', 'flow' or 'all', got {args.part!r}")
    check_output_dir(args.out_dir, args.write_shipped_weights)
    if args.threads:
        torch.set_num_threads(args.threads)
    cfg = load_config(args.config)
    d = setup_distributed()
    if d.main:
        Path(args.out_dir).mkdir(parents=True, exist_ok=True)
        (Path(args.out_dir) / f"args_{args.part}.json").write_text(
            json.dumps(asdict(args) | {"world": d.world}, indent=2)
        )
    run = Stage1Run()
    if args.part in ("vae", "all"):
        run.checkpoints["ss_vae"], models = train_vae(args, cfg, d)
        run.models |= models
    if args.part in ("flow", "all"):
        run.checkpoints["stage1"], models = train_flow(args, cfg, d)
        run.models |= models
    return run


def export_weights(
    run_dir: str | Path, dest: str | Path, dtype: torch.dtype = torch.float16
) -> dict[str, Path]:
    """Copy a run's final checkpoints for shipping: ``dest/ss_vae`` and ``dest/stage1``,
    and ``dest/foreground`` when the run has a silhouette net (``run_dir/foreground``,
    from ``python -m generator.pact.training.train_foreground --out RUN_DIR``); floating-point
    tensors stored in ``dtype`` (loading casts back to float32)."""
    run_dir, dest = Path(run_dir), Path(dest)
    vae = load_checkpoint(run_dir / "vae/checkpoint/ss_vae")
    half = copy.deepcopy(vae).to(dtype)
    out = {"ss_vae": save_checkpoint(half, dest / "ss_vae", {"dtype": str(dtype)})}
    models, cfg, stats = load_stage1(run_dir / "flow/checkpoint/stage1")
    out["stage1"] = save_stage1(models, cfg, dest / "stage1", stats, dtype=dtype)
    if (run_dir / "foreground").is_dir():
        net = load_checkpoint(run_dir / "foreground").to(dtype)
        out["foreground"] = save_checkpoint(net, dest / "foreground", {"dtype": str(dtype)})
    return out


def _parse() -> Args:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    names = {"data_dir": "--data", "out_dir": "--out"}
    for f in fields(Args):
        flag = names.get(f.name, "--" + f.name.replace("_", "-"))
        if f.type in ("bool", "bool | None"):
            p.add_argument(
                flag, dest=f.name, default=f.default, action=argparse.BooleanOptionalAction
            )
        else:
            kind = {"int": int, "float": float}.get(str(f.type).split(" ")[0], str)
            p.add_argument(flag, dest=f.name, default=f.default, type=kind)
    return Args(**vars(p.parse_args()))


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    args = _parse()
    kw = {
        k: v
        for k, v in asdict(args).items()
        if k not in ("data_dir", "out_dir", "config", "part", "steps", "resume")
    }
    train_stage1(args.data_dir, args.out_dir, args.config, args.part, args.steps, args.resume, **kw)
    if dist.is_initialized():
        dist.destroy_process_group()


if __name__ == "__main__":
    main()
