"""Render the bundled example inputs: examples/images/<name>.png, .mask.png, .json.

    .venv/bin/python scripts/make_examples.py [--out examples/images]

Objects come from the procedural factory's *test* split (never in the retrieval
library or the training data); one front-hemisphere view each, at rest, 256x256.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from PIL import Image

from generator.data.render import ObjectRenderer, ViewConfig, sample_view
from generator.procedural import object_id, sample_object

EXAMPLES = [
    ("cabinet", 1),
    ("cabinet", 2),
    ("desk", 1),
    ("microwave", 1),
    ("oven", 1),
    ("dishwasher", 1),
    ("refrigerator", 1),
    ("washing_machine", 1),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=Path("examples/images"))
    ap.add_argument("--size", type=int, default=256)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for k, (cat, seed) in enumerate(EXAMPLES):
        obj = sample_object(cat, seed, split="test")
        name = object_id(cat, seed, "test")
        rng = np.random.default_rng(1000 + k)
        with ObjectRenderer(obj, args.size, rng) as renderer:
            rv = renderer.render(sample_view(obj, rng, args.size, ViewConfig(open_fraction=0.0)))
        Image.fromarray(rv.rgb).save(args.out / f"{name}.png")
        Image.fromarray(rv.mask).save(args.out / f"{name}.mask.png")
        height = float(obj.bounds()[1, 2] - obj.bounds()[0, 2])
        hints = {"category": cat, "height": round(height, 3)}
        (args.out / f"{name}.json").write_text(json.dumps(hints, indent=2) + "\n")
        print(args.out / f"{name}.png")


if __name__ == "__main__":
    main()
