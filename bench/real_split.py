"""Write the real dev split: PartNet-Mobility objects as product photos and in rooms.

    .venv/bin/python bench/real_split.py [--data /work/data/partnet] [--out /work/data/real_split]
        [--views 2] [--styles product room] [--seed 0] [--image-size 256] [--limit N] [--ids ID ...]

Every object folder listed in DATA/index.json (else every PartNet-Mobility folder under
DATA) that is not in ``--exclude`` (default /work/shared/excluded-partnet-ids.txt; those
ids are never opened) is imported with ``asset_pipeline.importers.partnet.convert_object``
(default options: normalized, ``scale = None``) and rendered by
``generator.data.real_split.write_real_split`` in both styles, ``--views`` views each.
Objects the importer refuses (nothing to articulate) are listed under ``failed`` in
the manifest. The source repository, path and commit of every object come from the
index. Resumable and deterministic; prints a JSON summary. The split holds renders of
third-party data: it is refused inside this repository.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from asset_pipeline.importers.partnet import PartnetOptions, convert_object, find_objects  # noqa: E402
from generator.data.real_split import (  # noqa: E402
    DEFAULT_REAL_SPLIT,
    STYLES,
    SplitSource,
    write_real_split,
)

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = Path("/work/data/partnet")
DEFAULT_EXCLUDE = Path("/work/shared/excluded-partnet-ids.txt")


def _ids(path: Path | None) -> set[str]:
    if path is None or not path.is_file():
        return set()
    lines = (line.split("#")[0].strip() for line in path.read_text().splitlines())
    return {line for line in lines if line}


def sources(data: Path, exclude: set[str], only: set[str] | None = None) -> list[SplitSource]:
    """One SplitSource per object folder of ``data`` (index order), excluded ids left out."""
    index = data / "index.json"
    if index.is_file():
        entries = json.loads(index.read_text())
        items = [(str(e["id"]), data / str(e["id"]), e) for e in entries]
    else:
        items = [(f.name, f, {}) for f in find_objects(data)]
    out = []
    for oid, folder, entry in items:
        if oid in exclude or (only and oid not in only) or not folder.is_dir():
            continue
        source = {
            k: entry[k]
            for k in ("source_repo", "source_path", "source_commit", "model_cat")
            if k in entry
        }

        def load(folder: Path = folder):  # noqa: ANN202
            return convert_object(folder, PartnetOptions())

        out.append(SplitSource(oid, load, source))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="PartNet-Mobility folders.")
    ap.add_argument("--out", type=Path, default=DEFAULT_REAL_SPLIT, help="The split folder.")
    ap.add_argument("--exclude", type=Path, default=DEFAULT_EXCLUDE, help="Ids never opened.")
    ap.add_argument("--views", type=int, default=2, help="Views per style and object.")
    ap.add_argument("--styles", nargs="+", default=list(STYLES), choices=STYLES)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--image-size", type=int, default=256)
    ap.add_argument("--supersample", type=int, default=2, help="Render at N x the size.")
    ap.add_argument("--limit", type=int, default=None, help="Only the first N objects.")
    ap.add_argument("--ids", nargs="+", default=None, help="Only these object ids.")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")

    out = args.out.resolve()
    if out == REPO or REPO in out.parents:
        sys.exit(
            f"{out} is inside the repository; renders of PartNet-Mobility objects stay out of it"
        )
    exclude = _ids(args.exclude)
    srcs = sources(args.data, exclude, set(args.ids) if args.ids else None)[: args.limit]
    t0 = time.perf_counter()
    manifest = write_real_split(
        out,
        srcs,
        styles=args.styles,
        views=args.views,
        image_size=args.image_size,
        seed=args.seed,
        supersample=args.supersample,
    )
    images = manifest["images"]
    summary = {
        "out": str(out),
        "objects": len(manifest["objects"]),
        "images": len(images),
        "failed": manifest["failed"],
        "excluded_listed": len(exclude),
        "objects_per_category": dict(Counter(o["category"] for o in manifest["objects"])),
        "images_per_style": dict(Counter(im["style"] for im in images)),
        "seconds": round(time.perf_counter() - t0, 1),
    }
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
