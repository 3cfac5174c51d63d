"""Train the foreground U-Net (``foreground.ForegroundNet``) on a dataset folder.

    python -m generator.pact.training.train_foreground --data runs/data/train --out runs/pact/stage1 \
        --steps 600 --threads 1

One sample is a random (object, view) image of the training split with its silhouette
(part mask != 0) as the target, brightness/contrast jitter and horizontal flips; the
loss is BCE + soft Dice. Writes ``OUT/foreground`` (a checkpoint) and
``OUT/foreground_val.json`` (IoU on every view of the validation objects).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

import torch

from generator.pact.model.checkpoint import save_checkpoint
from generator.pact.model.foreground import ForegroundConfig, ForegroundNet, iou, segmentation_loss
from generator.pact.training.stage1_data import Stage1Dataset

log = logging.getLogger(__name__)


def _augment(images: torch.Tensor, g: torch.Generator) -> torch.Tensor:
    """Per-image brightness and contrast jitter."""
    B = len(images)
    gain = 0.8 + 0.4 * torch.rand(B, 1, 1, 1, generator=g)
    bias = 0.1 * (torch.rand(B, 1, 1, 1, generator=g) - 0.5)
    return (images * gain + bias).clamp(0, 1)


def train_foreground(
    data_dir: str | Path,
    out_dir: str | Path,
    steps: int = 2000,
    batch_size: int = 16,
    lr: float = 2e-3,
    seed: int = 0,
    threads: int | None = None,
    cfg: ForegroundConfig | None = None,
    val_fraction: float = 0.05,
) -> dict[str, float]:
    """Train on the dataset's (image, mask != 0) pairs; writes ``out_dir/foreground``
    (a checkpoint) and ``out_dir/foreground_val.json`` (validation IoU); returns it."""
    if threads:
        torch.set_num_threads(threads)
    cfg = cfg or ForegroundConfig()
    train = Stage1Dataset(data_dir, 64, "train", val_fraction, cfg.image_size)
    val = Stage1Dataset(data_dir, 64, "val", val_fraction, cfg.image_size)
    torch.manual_seed(seed)
    net = ForegroundNet(cfg)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, lr, total_steps=steps, pct_start=0.05)
    g = torch.Generator().manual_seed(seed)
    t0 = time.time()
    for step in range(1, steps + 1):
        items = torch.randint(len(train), (batch_size,), generator=g).tolist()
        rows = [train.view(*divmod(i, train.views)) for i in items]
        images = _augment(torch.stack([r[0] for r in rows]), g)
        target = torch.stack([r[1] for r in rows]) > 0
        flip = torch.rand(batch_size, generator=g) < 0.5
        images[flip], target[flip] = images[flip].flip(-1), target[flip].flip(-1)
        loss = segmentation_loss(net(images), target)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        if step % 100 == 0 or step == steps:
            log.info("foreground step %d loss %.4f (%.0fs)", step, loss.item(), time.time() - t0)
    net.eval()
    preds, targets = [], []
    for obj in range(val.num_objects):
        for v in range(val.views):
            image, mask = val.view(obj, v)
            preds.append(net.predict(image[None])[0])
            targets.append(mask > 0)
    metrics = {
        "val_iou": iou(torch.stack(preds), torch.stack(targets)),
        "val_images": len(preds),
        "steps": steps,
        "batch_size": batch_size,
        "seconds": time.time() - t0,
    }
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    save_checkpoint(net, out / "foreground", extra={"metrics": metrics})
    (out / "foreground_val.json").write_text(json.dumps(metrics, indent=2))
    log.info("foreground: validation IoU %.4f on %d images", metrics["val_iou"], len(preds))
    return metrics


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description="Train the foreground U-Net on a dataset folder.")
    ap.add_argument("--data", required=True, help="dataset folder (docs/dataset.md)")
    ap.add_argument("--out", default="runs/pact/foreground")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--batch-size", type=int, default=16)
    ap.add_argument("--lr", type=float, default=2e-3)
    ap.add_argument("--threads", type=int, default=None)
    a = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    m = train_foreground(a.data, a.out, a.steps, a.batch_size, a.lr, threads=a.threads)
    print(json.dumps(m))


if __name__ == "__main__":
    main()
