"""Train the photo parser (``ParserNet``) on parser data. Read top to bottom: ``Args``,
the losses, the evaluation, the loop.

    python -m generator.parser.train --data /work/data/parser_data --out runs/parser
    python -m generator.parser.train ... --steps 20000      # later: continue to 20k (resumes)

One sample is one augmented crop round the object (``generator.parser.data``); the
first ``small_fraction`` of the steps use smaller crops (progressive resizing: the
network is fully convolutional, a 128-px step costs under half a 192-px one). Loss:
cross-entropy of the three pixel classes, BCE + dice of the part-edge map, cross-entropy
of the motion on movable pixels and of the category. AdamW, linear warm-up then cosine, bf16 autocast
on CPU (AMX), an exponential moving average of the weights (what is exported).

Resumable: ``OUT/checkpoint/state.pt`` (model, EMA, optimiser, step) every
``ckpt_every`` steps, written under a temporary name and renamed; re-running the same
command continues from it. Batches are drawn from (seed, step), so a resumed run sees
what an uninterrupted one would, as long as the data folder has not grown (the item
list is re-read every ``reload_every`` steps: the data engine may still be writing).
Every ``eval_every`` steps the EMA weights are measured on the data's ``val`` items and
written to ``OUT/weights_<step>/`` (``bench/parser.py --weights`` reads them); the curve
goes to ``OUT/log.csv``.
"""

from __future__ import annotations

import argparse
import copy
import csv
import json
import logging
import math
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from torch.utils.data import DataLoader

from generator.parser.data import ParserDataset, StepBatches, mixed_items, write_motion_prior
from generator.parser.model import (
    ParserConfig,
    ParserNet,
    cpu_has_native_bf16,
    load_weights,
    save_weights,
)

log = logging.getLogger(__name__)


@dataclass
class Args:
    data: str = "/work/data/parser_data"
    out: str = "runs/parser"
    steps: int = 12000
    batch: int = 16
    lr: float = 2e-3
    weight_decay: float = 1e-4
    warmup: int = 300
    size: int = 192  # training crops (inference resamples the object's crop to this)
    small_size: int = 128  # progressive resizing: the first ``small_fraction`` of the
    small_fraction: float = 0.4  # steps train on crops this small (cheaper, same network)
    channels: str = "16,32,64,128,256"  # encoder widths at 1/2 .. 1/32
    blocks: str = "0,1,2,2,2"
    decoder_channels: str = "16,32,64,128"
    boundary_weight: float = 1.0
    boundary_pos_weight: float = 3.0  # boundary pixels are few
    motion_weight: float = 1.0
    category_weight: float = 0.5
    box: bool = True  # the part-box head (ParserConfig.box)
    box_weight: float = 1.0
    label_smoothing: float = 0.05
    ema: float = 0.999
    bf16: bool = True
    threads: int = 1  # 1 is fastest on a shared 2-core machine (no OpenMP spinning)
    workers: int = 1
    seed: int = 0
    ckpt_every: int = 200
    eval_every: int = 1000
    eval_items: int = 400
    reload_every: int = 1000
    max_minutes: float = 0.0  # stop (after a checkpoint) after this long; 0: no limit
    init_from: str = ""  # a weights folder to start from (fresh optimiser and schedule)
    extra_data: str = ""  # more parser-data folders, comma-separated (renders of real
    extra_repeat: int = 1  # objects, other seeds) whose train items join the batches' draw
    # this many times over
    resume: bool = True


def model_config(args: Args) -> ParserConfig:
    ints = lambda s: tuple(int(v) for v in s.split(","))  # noqa: E731
    return ParserConfig(
        image_size=args.size,
        channels=ints(args.channels),
        blocks=ints(args.blocks),
        decoder_channels=ints(args.decoder_channels),
        box=args.box,
    )


def lr_at(step: int, args: Args) -> float:
    if step < args.warmup:
        return args.lr * (step + 1) / args.warmup
    t = (step - args.warmup) / max(1, args.steps - args.warmup)
    return args.lr * (0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * min(1.0, t))))


def losses(out, batch: dict[str, torch.Tensor], args: Args) -> dict[str, torch.Tensor]:
    """out: ParserOutput; batch: seg, boundary, motion (B, h, w), category (B,)."""
    seg = F.cross_entropy(out.seg.float(), batch["seg"])
    b_logit = out.boundary.float()[:, 0]
    b_target = batch["boundary"]
    bce = F.binary_cross_entropy_with_logits(
        b_logit, b_target, pos_weight=torch.tensor(args.boundary_pos_weight)
    )
    p = b_logit.sigmoid()
    dice = 1 - (2 * (p * b_target).sum() + 1) / (p.sum() + b_target.sum() + 1)
    boundary = bce + dice
    motion = F.cross_entropy(out.motion.float(), batch["motion"], ignore_index=-1)
    if not (batch["motion"] >= 0).any():
        motion = out.motion.float().sum() * 0.0
    category = F.cross_entropy(
        out.category.float(), batch["category"], label_smoothing=args.label_smoothing
    )
    total = (
        seg
        + args.boundary_weight * boundary
        + args.motion_weight * motion
        + args.category_weight * category
    )
    terms = {"seg": seg, "boundary": boundary, "motion": motion, "category": category}
    if out.box is not None:
        terms["box"] = box_loss(out.box.float(), batch["box"], batch["seg"] == 2)
        total = total + args.box_weight * terms["box"]
    return {"loss": total, **terms}


def box_loss(pred: torch.Tensor, target: torch.Tensor, on: torch.Tensor) -> torch.Tensor:
    """Mean 1 - IoU of the predicted and true part boxes over the movable pixels ``on``
    (B, h, w); pred and target (B, 4, h, w) distances to the left, top, right, bottom
    edges. Both boxes hold the pixel, so they always meet (the IoU loss of FCOS)."""
    if not on.any():
        return pred.sum() * 0.0
    p = pred.permute(0, 2, 3, 1)[on]  # (N, 4)
    t = target.permute(0, 2, 3, 1)[on]
    area_p = (p[:, 0] + p[:, 2]) * (p[:, 1] + p[:, 3])
    area_t = (t[:, 0] + t[:, 2]) * (t[:, 1] + t[:, 3])
    w = torch.minimum(p[:, 0], t[:, 0]) + torch.minimum(p[:, 2], t[:, 2])
    h = torch.minimum(p[:, 1], t[:, 1]) + torch.minimum(p[:, 3], t[:, 3])
    inter = w * h
    iou = inter / (area_p + area_t - inter).clamp_min(1e-8)
    return (1 - iou).mean()


@torch.no_grad()
def evaluate(model: nn.Module, ds: ParserDataset, args: Args, batch: int = 16) -> dict[str, float]:
    """Pixel-class IoUs, boundary IoU, motion accuracy (movable pixels) and category
    accuracy of ``model`` on ``ds`` (no augmentation)."""
    model.eval()
    n = min(len(ds), args.eval_items)
    inter = np.zeros(4)  # background, base, part, boundary
    union = np.zeros(4)
    mot_ok = mot_n = cat_ok = 0
    box_iou, box_n = 0.0, 0
    for s in range(0, n, batch):
        items = [ds[(i, 0)] for i in range(s, min(n, s + batch))]
        b = {k: torch.stack([it[k] for it in items]) for k in items[0]}
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=args.bf16):
            out = model(b["image"].contiguous(memory_format=torch.channels_last))
        seg = out.seg.float().argmax(1)
        for c in range(3):
            inter[c] += ((seg == c) & (b["seg"] == c)).sum().item()
            union[c] += ((seg == c) | (b["seg"] == c)).sum().item()
        bd, bt = out.boundary.float()[:, 0] > 0, b["boundary"] > 0.5
        inter[3] += (bd & bt).sum().item()
        union[3] += (bd | bt).sum().item()
        mv = b["motion"] >= 0
        mot_ok += (out.motion.float().argmax(1)[mv] == b["motion"][mv]).sum().item()
        mot_n += mv.sum().item()
        cat_ok += (out.category.argmax(1) == b["category"]).sum().item()
        if out.box is not None and mv.any():
            box_iou += (1 - box_loss(out.box.float(), b["box"], mv).item()) * mv.sum().item()
            box_n += mv.sum().item()
    iou = inter / np.maximum(union, 1)
    model.train()
    return {
        "miou": float(iou[:3].mean()),
        "iou_bg": float(iou[0]),
        "iou_base": float(iou[1]),
        "iou_part": float(iou[2]),
        "iou_boundary": float(iou[3]),
        "motion_acc": mot_ok / max(1, mot_n),
        "category_acc": cat_ok / max(1, n),
        **({"box_iou": box_iou / box_n} if box_n else {}),
    }


class CurveLog:
    """Rows of scalars in OUT/log.csv; on resume, rows after the resumed step are dropped."""

    def __init__(self, path: Path, start: int) -> None:
        self.path = path
        self.rows: list[dict[str, str]] = []
        if start > 0 and path.is_file():
            with path.open() as f:
                self.rows = [r for r in csv.DictReader(f) if int(r["step"]) <= start]

    def write(self, step: int, scalars: dict[str, float]) -> None:
        self.rows.append({"step": str(step), **{k: f"{v:.5g}" for k, v in scalars.items()}})
        keys: list[str] = []
        for r in self.rows:
            keys += [k for k in r if k not in keys]
        tmp = self.path.with_suffix(".tmp")
        with tmp.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=keys)
            w.writeheader()
            w.writerows(self.rows)
        tmp.replace(self.path)


def save_state(out: Path, model, ema, opt, step: int, args: Args) -> None:  # noqa: ANN001
    tmp = out / "checkpoint.tmp"
    tmp.mkdir(parents=True, exist_ok=True)
    torch.save(
        {
            "model": model.state_dict(),
            "ema": ema.state_dict(),
            "optimizer": opt.state_dict(),
            "step": step,
            "args": asdict(args),
            "config": model.cfg.to_dict(),
        },
        tmp / "state.pt",
    )
    final = out / "checkpoint"
    old = out / "checkpoint.old"
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    if old.exists():
        import shutil

        shutil.rmtree(old)


def train(args: Args) -> Path:
    torch.set_num_threads(args.threads)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "args.json").write_text(json.dumps(asdict(args), indent=2))
    device = torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if args.bf16 and device.type == "cpu" and not cpu_has_native_bf16():
        log.warning(
            "--bf16 on a CPU without native bfloat16 (no AVX512-BF16 or AMX): torch emulates "
            "it, about ten times slower than --no-bf16"
        )
    torch.manual_seed(args.seed)

    model = ParserNet(model_config(args))
    if args.init_from:  # its weights where the shapes agree (a new head starts fresh)
        start, _ = load_weights(args.init_from)
        own = model.state_dict()
        same = {k: v for k, v in start.state_dict().items() if k in own and own[k].shape == v.shape}
        model.load_state_dict(same, strict=False)
        log.info("init from %s: %d of %d tensors", args.init_from, len(same), len(own))
    model = model.to(device, memory_format=torch.channels_last)
    ema = copy.deepcopy(model).eval()
    for p in ema.parameters():
        p.requires_grad_(False)
    opt = torch.optim.AdamW(
        model.parameters(), lr=args.lr, betas=(0.9, 0.99), weight_decay=args.weight_decay
    )
    step = 0
    state_path = out / "checkpoint" / "state.pt"
    if args.resume and state_path.is_file():
        st = torch.load(state_path, map_location=device, weights_only=False)
        model.load_state_dict(st["model"])
        ema.load_state_dict(st["ema"])
        opt.load_state_dict(st["optimizer"])
        step = int(st["step"])
        log.info("resumed at step %d", step)
    curve = CurveLog(out / "log.csv", step)
    val = ParserDataset(args.data, "val", args.size, augment=False)
    log.info(
        "model %.2f M parameters; val items %d",
        sum(p.numel() for p in model.parameters()) / 1e6,
        len(val),
    )

    t0 = time.time()
    acc: dict[str, float] = {}
    n_acc = 0
    t_log = time.time()
    autocast = dict(device_type=device.type, dtype=torch.bfloat16, enabled=args.bf16)
    switch = int(args.small_fraction * args.steps)
    timed_out = False
    while step < args.steps and not timed_out:
        size = args.small_size if step < switch else args.size
        items = (
            mixed_items(args.data, args.extra_data.split(","), args.extra_repeat)
            if args.extra_data
            else None
        )
        ds = ParserDataset(args.data, "train", size, augment=True, items=items)
        stop = min(args.steps, (step // args.reload_every + 1) * args.reload_every)
        if step < switch:
            stop = min(stop, switch)
        loader = DataLoader(
            ds,
            batch_sampler=StepBatches(len(ds), args.batch, args.seed, step, stop),
            num_workers=args.workers,
            prefetch_factor=4 if args.workers else None,
        )
        for batch in loader:
            batch = {k: v.to(device) for k, v in batch.items()}
            for g in opt.param_groups:
                g["lr"] = lr_at(step, args)
            with torch.autocast(**autocast):
                outs = model(batch["image"].contiguous(memory_format=torch.channels_last))
            ls = losses(outs, batch, args)
            opt.zero_grad(set_to_none=True)
            ls["loss"].backward()
            gn = torch.nn.utils.clip_grad_norm_(model.parameters(), 2.0)
            opt.step()
            with torch.no_grad():
                d = min(args.ema, (1 + step) / (10 + step))
                for pe, pm in zip(ema.parameters(), model.parameters(), strict=True):
                    pe.lerp_(pm, 1 - d)
                for be, bm in zip(ema.buffers(), model.buffers(), strict=True):
                    be.copy_(bm)
            step += 1
            for k, v in ls.items():
                acc[k] = acc.get(k, 0.0) + float(v.detach())
            acc["grad_norm"] = acc.get("grad_norm", 0.0) + float(gn)
            n_acc += 1
            evaluate_now = step % args.eval_every == 0 or step == args.steps
            if step % args.ckpt_every == 0 or evaluate_now:
                row = {f"train/{k}": v / n_acc for k, v in acc.items()}
                row["lr"] = lr_at(step - 1, args)
                row["samples_per_s"] = n_acc * args.batch / (time.time() - t_log)
                row["train_items"] = len(ds)
                row["crop_size"] = size
                if evaluate_now:
                    row.update({f"val/{k}": v for k, v in evaluate(ema, val, args).items()})
                    save_weights(
                        ema, out / f"weights_{step:06d}", {"step": step, "args": asdict(args)}
                    )
                    write_motion_prior(args.data, out / f"weights_{step:06d}")
                save_state(out, model, ema, opt, step, args)
                curve.write(step, row)
                log.info("step %d %s", step, {k: round(v, 4) for k, v in row.items()})
                acc, n_acc, t_log = {}, 0, time.time()
                if args.max_minutes and (time.time() - t0) / 60 > args.max_minutes:
                    log.info("time limit reached at step %d", step)
                    timed_out = True
                    break
            if step >= stop:
                break
    # the weights of where the run stopped (its end, or the time limit; a resume goes on)
    save_weights(ema, out / "weights", {"step": step, "args": asdict(args)})
    write_motion_prior(args.data, out / "weights")
    return out


def parse_args(argv: list[str] | None = None) -> Args:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for f in fields(Args):
        flag = "--" + f.name.replace("_", "-")
        if f.type in ("bool", bool):
            ap.add_argument(flag, action=argparse.BooleanOptionalAction, default=f.default)
        else:
            typ = {"int": int, "float": float, "str": str}[
                f.type if isinstance(f.type, str) else f.type.__name__
            ]
            ap.add_argument(flag, type=typ, default=f.default)
    return Args(**vars(ap.parse_args(argv)))


def main(argv: list[str] | None = None) -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    train(parse_args(argv))


if __name__ == "__main__":
    main()
