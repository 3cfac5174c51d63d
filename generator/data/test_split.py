"""The fixed generation test split: held-out procedural objects, rendered, with ground truth.

``write_test_split(out)`` writes an image folder in the input format ``pact convert``
reads (``out/images/<id>.png``, ``.mask.png``, ``.json`` hints with the category) and
the ground-truth bundles beside it (``out/gt/<id>/object.json`` + parts). Objects come
from the factory's ``test`` split (parameter ranges never used for training, see
``generator.procedural.HELD_OUT``) with seeds starting at ``TEST_SEED0``, far from the
training seeds; views are drawn like the training views, at rest. Deterministic.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from generator.atomic_files import atomic_write_bytes
from generator.bundle import save_bundle

TEST_SEED0 = 900_000


def write_test_split(
    out: str | Path,
    per_category: int = 6,
    *,
    image_size: int = 256,
    seed0: int = TEST_SEED0,
    categories: tuple[str, ...] | None = None,
) -> list[str]:
    """Write ``per_category`` held-out objects per category; returns their ids."""
    from io import BytesIO

    from generator.data.render import ObjectRenderer, ViewConfig, sample_view
    from generator.procedural import CATEGORIES, object_id, sample_object

    out = Path(out)
    ids = []
    for cat in categories or CATEGORIES:
        for k in range(per_category):
            seed = seed0 + k
            oid = object_id(cat, seed, "test")
            ids.append(oid)
            if (out / "gt" / oid / "object.json").is_file() and (
                out / "images" / f"{oid}.json"
            ).is_file():
                continue  # resumable
            obj = sample_object(cat, seed, split="test")
            rng = np.random.default_rng([seed, sum(map(ord, cat))])
            with ObjectRenderer(obj, image_size, rng) as renderer:
                rv = renderer.render(
                    sample_view(obj, rng, image_size, ViewConfig(open_fraction=0.0))
                )
            for name, arr in ((f"{oid}.png", rv.rgb), (f"{oid}.mask.png", rv.mask)):
                buf = BytesIO()
                Image.fromarray(arr).save(buf, format="PNG")
                atomic_write_bytes(out / "images" / name, buf.getvalue())
            save_bundle(obj, out / "gt" / oid)
            hints = {"category": cat}
            atomic_write_bytes(out / "images" / f"{oid}.json", json.dumps(hints).encode())
    return ids
