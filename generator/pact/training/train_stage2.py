"""Train PAct stage 2: the SLAT VAE, then the structure-conditioned flow + articulation head.

    python -m generator.pact.training.train_stage2 cache  --data runs/data/train
    python -m generator.pact.training.train_stage2 vae    --data runs/data/train --minutes 15
    python -m generator.pact.training.train_stage2 flow   --data runs/data/train --minutes 45 --threads 1
    python -m generator.pact.training.train_stage2 eval-vae --data runs/data/train --threads 1
    python -m generator.pact.training.train_stage2 head-stage1 --minutes 6 --threads 1   # ablation

On a 2-core machine shared with other jobs use ``--threads 1``: two OpenMP threads
spin-wait for each other (a flow step took 7 s with 2 threads, 0.5-0.9 s with 1).

Reads top to bottom: arguments, data, the loop, checkpoints. Both stages hold out the
last ``--holdout`` objects of the dataset (never trained on) for the reported figures.
Checkpoints go to ``--out`` (default runs/pact/stage2/weights/{slat_vae,stage2,stage1_head})
in float16; logs (text + TensorBoard) to ``--logdir``. The models a step builds on (the
SLAT VAE for ``flow``, stage 1 for ``head-stage1``) are read from ``--out`` when it holds
them, else from ``--base`` (default: the shipped weights). Writing into the shipped
weights folder (generator/pact/weights/), with any of ``--out``, ``--cache`` or
``--logdir``, needs ``--write-shipped-weights`` (:func:`check_written_folders`).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from generator.data.shards import read_manifest
from generator.pact.model import model_configs
from generator.pact.model.checkpoint import check_output_dir, load_checkpoint, save_checkpoint
from generator.pact.model.preprocess import encoder_inputs
from generator.pact.model.slat_vae import (
    SlatVAE,
    SlatVAETrainConfig,
    decode_part_mesh,
    sparse_parts,
    vae_loss,
)
from generator.pact.model.stage2 import CONFIG_DIR
from generator.pact.training.stage2_data import SlatObjects, build_cache, dequantize_sdf

log = logging.getLogger("pact.train_stage2")

WEIGHTS = Path(__file__).parents[1] / "weights" / "small"


def model_dir(args: argparse.Namespace, name: str) -> Path:
    """Where a model this step builds on is read from: ``--out`` when it has it, else ``--base``."""
    own = Path(args.out) / name
    return own if own.is_dir() else Path(args.base) / name


def save_fp16(model: torch.nn.Module, path: Path, extra: dict | None = None) -> Path:
    """Checkpoint with float tensors stored as float16 (loaded back as float32)."""
    half = type(model)(model.cfg)
    half.load_state_dict(model.state_dict())
    half = half.half()
    return save_checkpoint(half, path, extra)


def load_fp32(path: Path, device: str = "cpu") -> torch.nn.Module:
    return load_checkpoint(path, device).float()


# --------------------------------------------------------------------------- SLAT VAE


def vae_batch(
    data: SlatObjects, objects: list[int], device: str
) -> tuple[torch.Tensor, torch.Tensor, object]:
    """sdf (N, 64), rgb (N, 3) in [-1, 1] and the SparseParts of the objects' parts."""
    P = data.max_parts
    rows = np.concatenate([np.arange(data.rows(i).start, data.rows(i).stop) for i in objects])
    local = np.repeat(
        np.arange(len(objects)), [data.rows(i).stop - data.rows(i).start for i in objects]
    )
    group = torch.from_numpy(local * P + data.slot[rows].astype(np.int64))
    occ = torch.from_numpy(np.concatenate([data.occupancy(i) for i in objects]))  # (n*P, R, R, R)
    sp = sparse_parts(torch.from_numpy(data.coords[rows].astype(np.int64)), group, occ)
    sp = type(sp)(*(t.to(device) for t in sp))
    sdf = torch.from_numpy(dequantize_sdf(data.sdf_q[rows])).to(device)
    rgb = torch.from_numpy(data.rgb[rows].astype(np.float32) / 127.5 - 1.0).to(device)
    return sdf, rgb, sp


def train_vae(args: argparse.Namespace) -> None:
    from torch.utils.tensorboard import SummaryWriter

    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    cfg = model_configs.read_config_json(args.config, CONFIG_DIR, "stage-2")
    tcfg = SlatVAETrainConfig(**cfg.get("vae_train", {}))
    data = SlatObjects(
        args.cache, args.data, images=False, max_parts=cfg["flow"]["max_parts"], partial=True
    )
    # the last --holdout objects of the whole dataset are never trained on
    n_total = sum(len(sh["objects"]) for sh in read_manifest(args.data)["shards"])
    n_train = min(len(data), n_total - args.holdout)
    model = model_configs.build("slat_vae", cfg["vae"]).to(args.device)
    opt = torch.optim.AdamW(model.parameters(), lr=tcfg.lr, weight_decay=0.0)
    writer = SummaryWriter(args.logdir + "/vae")
    t0, step = time.time(), 0
    budget = args.minutes * 60.0
    while True:
        elapsed = time.time() - t0
        if elapsed > budget or (args.steps and step >= args.steps):
            break
        lr = tcfg.lr * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * min(elapsed / budget, 1.0))))
        for g in opt.param_groups:
            g["lr"] = lr
        objs = rng.choice(n_train, tcfg.objects_per_batch, replace=False).tolist()
        sdf, rgb, sp = vae_batch(data, objs, args.device)
        rows = None
        if tcfg.voxels_per_batch and len(sdf) > tcfg.voxels_per_batch:
            rows = torch.from_numpy(rng.choice(len(sdf), tcfg.voxels_per_batch, replace=False))
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=tcfg.bf16):
            out = model(sdf, rgb, sp, rows=rows)
        if rows is not None:
            sdf, rgb = sdf[rows], rgb[rows]
        loss, m = vae_loss(out, sdf, rgb, tcfg)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        step += 1
        if step % 25 == 0:
            for k, v in m.items():
                writer.add_scalar(f"vae/{k}", v, step)
            log.info(
                "vae step %d %.0fs lr %.2e %s",
                step,
                elapsed,
                lr,
                " ".join(f"{k} {v:.4f}" for k, v in m.items()),
            )
    # latent statistics over a subset of the training objects
    model.eval()
    means = []
    with torch.no_grad():
        for i in rng.choice(n_train, min(64, n_train), replace=False).tolist():
            sdf, rgb, sp = vae_batch(data, [i], args.device)
            means.append(model.encode(sdf, rgb, sp)[0].float())
    allz = torch.cat(means)
    model.latent_mean.copy_(allz.mean(0))
    model.latent_std.copy_(allz.std(0).clamp(min=1e-3))
    extra = {
        "steps": step,
        "seconds": time.time() - t0,
        "train_objects": n_train,
        "train_config": asdict(tcfg),
    }
    save_fp16(model, Path(args.out) / "slat_vae", extra)
    log.info("saved SLAT VAE after %d steps (%.0f s)", step, time.time() - t0)


def eval_vae(args: argparse.Namespace) -> dict:
    """Reconstruction Chamfer (normalized units) and colour error on held-out objects."""
    from generator.data.shards import read_manifest
    from generator.metrics import chamfer

    vae = load_fp32(model_dir(args, "slat_vae")).eval()
    data = SlatObjects(args.cache, args.data, images=False, max_parts=8)
    manifest = read_manifest(args.data)
    per_shard = manifest["objects_per_shard"]
    n = len(data)
    idx = list(range(n - args.holdout, n))[: args.eval_objects]
    rng = np.random.default_rng(0)
    # "vae": decoded SDF/RGB; "reference": the cached targets themselves through the same
    # marching cubes (the floor set by the 128^3 grid, truncation and thin panels)
    acc: dict[str, dict[str, list[float]]] = {
        k: {"cd": [], "l1": [], "col": []} for k in ("vae", "reference")
    }
    sdf_err = []
    cached_shard, arrays = None, None
    from scipy.spatial import cKDTree

    for i in idx:
        k, j = divmod(i, per_shard)
        if cached_shard != k:
            with np.load(Path(args.data) / manifest["shards"][k]["file"]) as z:
                arrays = {key: z[key] for key in ("surface_points", "surface_colors")}
            cached_shard = k
        sdf, rgb, sp = vae_batch(data, [i], "cpu")
        with torch.no_grad():
            out = vae(sdf, rgb, sp, sample=False)
        sdf_err.append(float((out.sdf - sdf).abs().mean()))
        occ = data.occupancy(i)
        rows = data.rows(i)
        slots = data.slot[rows]
        versions = {
            "vae": (out.sdf.numpy(), ((out.rgb.numpy() + 1) * 127.5).round().clip(0, 255)),
            "reference": (sdf.numpy(), data.rgb[rows]),
        }
        for s in range(int(data.arrays["part_count"][i])):
            sel = slots == s
            gt_p = arrays["surface_points"][j, s]
            gt_c = arrays["surface_colors"][j, s].astype(np.float32)
            for name, (sdf_v, rgb_v) in versions.items():
                # the decoder's own surface (no occupancy constraint): the VAE's fidelity
                mesh = decode_part_mesh(
                    data.coords[rows][sel],
                    sdf_v[sel],
                    rgb_v[sel].astype(np.uint8),
                    occ[s],
                    constrain=False,
                )
                if mesh is None or len(mesh.faces) == 0:
                    continue
                pts = mesh.sample(2048, seed=int(rng.integers(1 << 30)))
                acc[name]["cd"].append(chamfer(pts, gt_p))
                d1, _ = cKDTree(gt_p).query(pts)
                d2, nn_ = cKDTree(mesh.vertices).query(gt_p)
                acc[name]["l1"].append(0.5 * (d1.mean() + d2.mean()))
                vc = mesh.visual.vertex_colors[nn_, :3].astype(np.float32)
                acc[name]["col"].append(float(np.abs(vc - gt_c).mean()))
    res = {"objects": len(idx), "sdf_l1_truncated_units": float(np.mean(sdf_err))}
    for name, a in acc.items():
        res[name] = {
            "parts": len(a["cd"]),
            "chamfer_squared_sum_mean": float(np.mean(a["cd"])),
            "chamfer_l1_mean": float(np.mean(a["l1"])),
            "colour_mae_0_255": float(np.mean(a["col"])),
        }
    log.info("SLAT VAE held-out: %s", res)
    print(json.dumps(res, indent=1))
    return res


# --------------------------------------------------------------------------- flow + head


def encode_all_latents(data: SlatObjects, vae: SlatVAE, cache: Path, device: str) -> np.ndarray:
    """Normalized latent means (M, C) of every token voxel, cached beside the SLAT cache
    (keyed by the VAE weights' size and modification time)."""
    wfile = Path(vae.source) / "model.safetensors" if hasattr(vae, "source") else None
    tag = f"{wfile.stat().st_size}_{int(wfile.stat().st_mtime)}" if wfile else "x"
    out = Path(cache) / f"latents_{tag}.npy"
    if out.is_file():
        z = np.load(out)
        if len(z) == len(data.coords):
            return z
    t0 = time.time()
    zs = []
    with torch.no_grad():
        for start in range(0, len(data), 8):
            sdf, rgb, sp = vae_batch(data, list(range(start, min(start + 8, len(data)))), device)
            mean, _ = vae.encode(sdf, rgb, sp)
            zs.append(vae.normalize(mean).float().cpu().numpy().astype(np.float16))
    z = np.concatenate(zs)
    np.save(out, z)
    log.info("encoded %d token voxels in %.0f s -> %s", len(z), time.time() - t0, out)
    return z


def flow_batch(data: SlatObjects, objects: list[int], cfg, rng: np.random.Generator):  # noqa: ANN001, ANN201
    """TokenBatch, images (B, 3, H, W) in [0, 1] (a random view each) and targets."""
    from generator.pact.model.articulation import ArticulationTargets
    from generator.pact.model.stage2 import collate, tokenize

    toks = []
    for i in objects:
        r = data.rows(i)
        toks.append(
            tokenize(
                data.coords[r],
                data.slot[r].astype(np.int64),
                data.occupancy(i),
                cfg.flow,
                data.latents[r].astype(np.float32),
            )
        )
    batch = collate(toks, cfg.flow.max_tokens)
    views = rng.integers(0, data.arrays["images"].shape[1], len(objects))
    img = np.stack([data.arrays["images"][i, v] for i, v in zip(objects, views, strict=True)])
    images = torch.from_numpy(img).permute(0, 3, 1, 2).float() / 255.0
    a = data.arrays
    tgt = ArticulationTargets(
        torch.from_numpy(a["joint_type"][objects].astype(np.int64)),
        torch.from_numpy(a["semantic"][objects].astype(np.int64)),
        torch.from_numpy(a["joint_origin"][objects]),
        torch.from_numpy(a["joint_axis"][objects]),
        torch.from_numpy(a["joint_range"][objects]),
    )
    return batch, images, tgt


def save_stage2(models: dict, out: Path, extra: dict) -> None:
    for role in ("image_encoder", "flow", "head"):
        save_fp16(models[role], out / "stage2" / role, extra)


def train_flow(args: argparse.Namespace) -> None:
    from torch.utils.tensorboard import SummaryWriter

    from generator.pact.model.stage2 import build_stage2, load_config, training_step

    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    cfg = load_config(args.config)
    tcfg = cfg.flow_train
    data = SlatObjects(args.cache, args.data, images=True, max_parts=cfg.flow.max_parts)
    vae = load_fp32(model_dir(args, "slat_vae"), args.device).eval()
    vae.source = str(model_dir(args, "slat_vae"))
    data.latents = encode_all_latents(data, vae, Path(args.cache), args.device)
    n_train = len(data) - args.holdout
    models = build_stage2(cfg)
    models.pop("vae")
    if args.resume and (Path(args.out) / "stage2" / "flow").is_dir():
        for role in models:
            models[role] = load_fp32(Path(args.out) / "stage2" / role)
        log.info("resumed from %s", Path(args.out) / "stage2")
    for m in models.values():
        m.to(args.device).train()
    params = [p for m in models.values() for p in m.parameters() if p.requires_grad]
    log.info(
        "stage-2 parameters: %s",
        {k: sum(p.numel() for p in m.parameters()) for k, m in models.items()},
    )
    opt = torch.optim.AdamW(params, lr=tcfg.lr, weight_decay=0.01)
    writer = SummaryWriter(args.logdir + "/flow")
    gen = torch.Generator().manual_seed(args.seed)
    t0, step, last_save = time.time(), 0, time.time()
    budget = args.minutes * 60.0
    hist: list[dict[str, float]] = []
    while True:
        elapsed = time.time() - t0
        if elapsed > budget or (args.steps and step >= args.steps):
            break
        warm = min(1.0, (step + 1) / 100)
        lr = (
            tcfg.lr
            * warm
            * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * min(elapsed / budget, 1.0))))
        )
        for g in opt.param_groups:
            g["lr"] = lr
        objs = rng.choice(n_train, tcfg.batch_size, replace=False).tolist()
        tokens, images, tgt = flow_batch(data, objs, cfg, rng)
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=tcfg.bf16):
            loss, m = training_step(
                models,
                tokens.to(args.device),
                images.to(args.device),
                type(tgt)(*(t.to(args.device) for t in tgt)),
                tcfg,
                gen,
            )
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(params, 1.0)
        opt.step()
        step += 1
        hist.append(m)
        if step % 20 == 0:
            avg = {k: float(np.mean([h.get(k, np.nan) for h in hist])) for k in hist[-1]}
            hist = []
            for k, v in avg.items():
                writer.add_scalar(f"flow/{k}", v, step)
            log.info(
                "flow step %d %.0fs lr %.2e %s",
                step,
                elapsed,
                lr,
                " ".join(f"{k} {v:.4f}" for k, v in avg.items()),
            )
        if time.time() - last_save > 600:
            save_stage2(models, Path(args.out), {"steps": step, "seconds": time.time() - t0})
            last_save = time.time()
    extra = {
        "steps": step,
        "seconds": time.time() - t0,
        "train_objects": n_train,
        "batch_size": tcfg.batch_size,
    }
    save_stage2(models, Path(args.out), extra)
    log.info("saved stage 2 after %d steps (%.0f s)", step, time.time() - t0)


def train_stage1_head(args: argparse.Namespace) -> None:
    """Ablation: the same articulation head on stage-1 last-block features.

    Stage 1 (shipped checkpoints) stays frozen; each step encodes the ground-truth part
    occupancies with the stage-1 VAE, noises them at one logit-normal t, runs the stage-1
    flow (image + mask of a random view) and trains the head on [MeanPool || MaxPool] of
    each slot's tokens (single-timestep features, as for stage 2). Saved to
    ``--out/stage1_head``.
    """
    from generator.pact.model.articulation import (
        ArticulationHeadConfig,
        ArticulationTargets,
        articulation_loss,
        pool_slots,
    )
    from generator.pact.model.flow import noisy, sample_t
    from generator.pact.model.model_configs import build
    from generator.pact.model.stage1 import LatentStats, load_stage1

    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    out = Path(args.out)
    s1, s1cfg, stats = load_stage1(model_dir(args, "stage1"), args.device)
    ss_vae = load_checkpoint(model_dir(args, "ss_vae"), args.device).float().eval()
    stats = stats or LatentStats()
    K = s1cfg.flow.max_parts
    data = SlatObjects(args.cache, args.data, images=True, max_parts=K)
    n_train = len(data) - args.holdout
    hcfg = ArticulationHeadConfig(in_dim=s1cfg.flow.width, hidden=256, layers=6)
    head = build("articulation_head", hcfg).to(args.device)
    opt = torch.optim.AdamW(head.parameters(), lr=5e-4)
    t0, step = time.time(), 0
    while time.time() - t0 < args.minutes * 60 and not (args.steps and step >= args.steps):
        objs = rng.choice(n_train, 8, replace=False).tolist()
        occ = torch.from_numpy(np.stack([data.occupancy(i) for i in objs])).to(args.device)
        views = rng.integers(0, data.arrays["images"].shape[1], len(objs))
        img = np.stack([data.arrays["images"][i, v] for i, v in zip(objs, views, strict=True)])
        mask = np.stack([data.arrays["masks"][i, v] for i, v in zip(objs, views, strict=True)])
        mask = np.where(mask > K, 0, mask)
        images = torch.from_numpy(img).permute(0, 3, 1, 2).float().div(255).to(args.device)
        with torch.no_grad():
            z0 = stats.normalize(ss_vae.encode_parts(occ))  # (B, K, C, r, r, r)
            t = sample_t(len(objs), device=args.device)
            m = torch.nn.functional.interpolate(
                torch.from_numpy(mask)[:, None].float(), size=images.shape[-2:], mode="nearest"
            )[:, 0].long()
            images, m = encoder_inputs(s1["image_encoder"], images, m.to(args.device))
            cond = s1["image_encoder"](images)
            feats = s1["flow"](noisy(z0, torch.randn_like(z0), t), t, cond, m).features
        pred = head(pool_slots(feats))
        a = data.arrays
        tgt = ArticulationTargets(
            *(torch.from_numpy(a[k][objs].astype(np.int64 if k in ("joint_type", "semantic") else np.float32))
              for k in ("joint_type", "semantic", "joint_origin", "joint_axis", "joint_range"))
        )  # fmt: skip
        present = (
            torch.arange(K)[None]
            < torch.from_numpy(a["part_count"][objs].astype(np.int64))[:, None]
        )
        loss, met = articulation_loss(
            pred, type(tgt)(*(x.to(args.device) for x in tgt)), present.to(args.device)
        )
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        step += 1
        if step % 20 == 0:
            log.info(
                "stage1-head step %d %.0fs %s",
                step,
                time.time() - t0,
                " ".join(f"{k} {v:.4f}" for k, v in met.items()),
            )
    save_fp16(head, out / "stage1_head", {"steps": step, "seconds": time.time() - t0})
    log.info("saved stage-1 articulation head after %d steps", step)


# --------------------------------------------------------------------------- entry


def written_folders(args: argparse.Namespace) -> dict[str, str]:
    """The folders the step ``args.what`` writes into, by option: ``--cache`` (``cache``
    builds it, ``flow`` adds its latents), ``--out`` (checkpoints of ``vae``, ``flow``,
    ``head-stage1``) and ``--logdir`` (logs of ``vae`` and ``flow``)."""
    folders = {}
    if args.what in ("cache", "flow"):
        folders["--cache"] = args.cache
    if args.what in ("vae", "flow", "head-stage1"):
        folders["--out"] = args.out
    if args.what in ("vae", "flow"):
        folders["--logdir"] = args.logdir
    return folders


def check_written_folders(args: argparse.Namespace) -> None:
    """Raise ValueError naming the option when a folder the step writes into
    (:func:`written_folders`) lies in the shipped weights and ``--write-shipped-weights``
    was not given (:func:`~generator.pact.model.checkpoint.check_output_dir`)."""
    for option, folder in written_folders(args).items():
        try:
            check_output_dir(folder, args.write_shipped_weights)
        except ValueError as e:
            raise ValueError(f"{option} {e}") from e


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The options of :func:`main`."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("what", choices=["cache", "vae", "flow", "eval-vae", "head-stage1"])
    ap.add_argument("--data", default="runs/data/train")
    ap.add_argument("--cache", default="runs/pact/slat_cache")
    ap.add_argument("--config", default="stage2_small", help="config name or JSON path")
    ap.add_argument("--out", default="runs/pact/stage2/weights", help="checkpoint folder")
    ap.add_argument("--base", default=str(WEIGHTS), help="weights the step builds on")
    ap.add_argument(
        "--write-shipped-weights",
        action="store_true",
        help="allow --out, --cache and --logdir inside generator/pact/weights/",
    )
    ap.add_argument("--logdir", default="runs/pact/stage2")
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument(
        "--steps", type=int, default=0, help="stop after this many steps (0: time only)"
    )
    ap.add_argument("--holdout", type=int, default=70)
    ap.add_argument("--eval-objects", type=int, default=30)
    ap.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--threads", type=int, default=0)
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    args = parse_args(argv)
    try:
        check_written_folders(args)
    except ValueError as e:
        raise SystemExit(f"error: {e}") from e
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.what == "cache":
        build_cache(args.data, args.cache)
    elif args.what == "vae":
        train_vae(args)
    elif args.what == "eval-vae":
        eval_vae(args)
    elif args.what == "flow":
        train_flow(args)
    else:
        train_stage1_head(args)


if __name__ == "__main__":
    main()
