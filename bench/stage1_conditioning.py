"""How much PAct stage 1's flow uses its condition (image, part mask) at high noise.

    python bench/stage1_conditioning.py [WEIGHTS ...] [--split runs/test_split] [--objects 14]

At t = 1 the noisy input is pure noise, so the velocity target ``eps - x_0`` can only be
predicted from the condition; a flow that ignores it does no better there than with the
null condition. For each weights folder (``ss_vae/`` + ``stage1/``, default the shipped
small model) this prints JSON: the mean velocity MSE over test-split objects at t = 0.9
and t = 1.0 with the image and the ground-truth mask, with the image only, and with the
null condition (the classifier-free-guidance branch), on the same noise. The targets
are the ground-truth part latents exactly as training builds them (VAE posterior means,
empty slots holding the empty-grid latent, normalized with the checkpoint's statistics).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from stage1 import part_grids  # noqa: E402

from generator.bundle import load_bundle  # noqa: E402
from generator.pact.inference.stage1_generator import Stage1Generator  # noqa: E402
from generator.pact.model.flow import noisy  # noqa: E402
from generator.pact.model.preprocess import encoder_inputs  # noqa: E402

TIMES = (0.9, 1.0)
CONDITIONS = ("image+mask", "image", "none")


@torch.no_grad()
def conditioning_mse(gen: Stage1Generator, split: Path, ids: list[str], seed: int = 0) -> dict:
    flow, vae = gen.models["flow"], gen.models["vae"]
    encoder, stats = gen.models["image_encoder"], gen.latent_stats
    T, R = flow.cfg.max_parts, vae.cfg.resolution
    errors: dict[str, list[float]] = {f"t={t} {c}": [] for t in TIMES for c in CONDITIONS}
    g = torch.Generator().manual_seed(seed)
    for oid in ids:
        gt = part_grids(load_bundle(split / "gt" / oid))[:T]  # (K, R, R, R)
        image = np.asarray(Image.open(split / "images" / f"{oid}.png").convert("RGB"))
        mask = np.asarray(Image.open(split / "images" / f"{oid}.mask.png"))
        img, m, _, _ = gen.inputs(image, mask)
        occ = torch.zeros(1, T, R, R, R)
        occ[0, : len(gt)] = torch.from_numpy(gt).float()
        z = vae.encode_parts(occ)
        z[0, len(gt) :] = vae.empty_latent()
        x0 = stats.normalize(z) if stats is not None else z
        # a foreground-cropping encoder: cropped by the mask, or by the silhouette net
        img_m, m = encoder_inputs(encoder, img, m)
        img_fg = img_m
        if encoder.cfg.foreground_crop and "foreground" in gen.models:
            img_fg, _ = encoder_inputs(encoder, img, None, gen.models["foreground"])
        cond, cond_fg = encoder(img_m), encoder(img_fg)
        for t in TIMES:
            eps = torch.randn(x0.shape, generator=g)
            tt = torch.full((1,), t)
            for name, c, mm in (
                ("image+mask", cond, m),
                ("image", cond_fg, None),
                ("none", None, None),
            ):
                v = flow(noisy(x0, eps, tt), tt, c, mm).velocity
                errors[f"t={t} {name}"].append(float((v - (eps - x0)).pow(2).mean()))
    return {k: round(float(np.mean(v)), 4) for k, v in errors.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("weights", nargs="*", default=[str(ROOT / "generator/pact/weights/small")])
    ap.add_argument("--split", default=str(ROOT / "runs/test_split"))
    ap.add_argument("--objects", type=int, default=14, help="every third test object, this many")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    from generator.data.test_split import write_test_split

    split = Path(args.split)
    ids = sorted(write_test_split(split))[::3][: args.objects]
    result = {"split": str(split), "objects": len(ids), "velocity_mse": {}}
    for w in args.weights:
        result["velocity_mse"][w] = conditioning_mse(Stage1Generator.load(w), split, ids)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
