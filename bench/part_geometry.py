"""Clean part geometry of PAct's output: pieces per part, closed pieces, RS-dCD. Prints JSON.

    nice .venv/bin/python bench/part_geometry.py [--examples examples/images]
        [--split-dir runs/test_split] [--per-category 6] [--real N] [--limit N]
        [--threads 1] [--out FILE]

For every input (the bundled examples, the 42-object test split with its part masks,
optionally the first N product photos of the real dev split) stage 1 and stage 2 run
once (``PActGenerator.run``); the decoded SDF is then meshed twice from the same
latents (``PActGenerator.mesh_parts``): ``raw`` (the marching cubes of the decoded SDF,
as before the clean-geometry change) and ``clean`` (the stage-1 occupancy fixes the
topology, ``generator.pact.model.slat_vae.constrain_sdf``, then ``part_cleaning.clean_mesh``).
Each is assembled (``assemble``, the network output) and given the box layout as
``PActGenerator.generate`` does (what ``pact convert`` builds): ``raw`` the layout of
the raw meshes, ``clean`` that same layout with the clean meshes as visuals
(``generator.pact.inference.generate.with_visuals``).

Per object and mode, on the assembled object: pieces of every movable part
(``len(mesh.split(only_watertight=False))``), whether it is one piece (a second piece
that ``part_cleaning.is_handle`` accepts aside), the base's pieces against the
26-connected components of its stage-1 occupancy, the share of parts whose every piece
is closed (watertight, consistently wound, positive volume), seconds (stage 1 + 2 +
decode are shared; ``mesh_s`` is the mode's own meshing). On the box-layout object:
movable parts in one group of touching pieces besides the bar handle (the layout's bar
is three overlapping closed solids). With ground truth (test split): the paper's
metrics (``generator.metrics.evaluate_pair``) of the assembled and the box-layout
object; ``mean`` averages them like ``bench/gen_quality.py``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from PIL import Image
from scipy import ndimage

from generator.articulated import ArticulatedObject
from generator.box_layout import fit_box_layout
from generator.bundle import load_bundle
from generator.mesh_repair.cleaning import TOUCH, groups, is_handle, pieces
from generator.mesh_repair.closing import is_closed
from generator.metrics import METRIC_KEYS, MetricError, evaluate_pair
from generator.pact.inference.generate import with_visuals

MODES = ("raw", "clean")


def _read(folder: Path, iid: str) -> tuple[np.ndarray, np.ndarray | None, dict[str, Any]]:
    img = np.asarray(Image.open(folder / f"{iid}.png").convert("RGB"))
    mp = folder / f"{iid}.mask.png"
    mask = np.asarray(Image.open(mp)) if mp.is_file() else None
    hp = folder / f"{iid}.json"
    hints = json.loads(hp.read_text()) if hp.is_file() else {}
    return img, mask, hints


def _one_piece(mesh) -> tuple[int, bool]:  # noqa: ANN001
    """(pieces, one piece with a handle aside)."""
    ps = pieces(mesh)
    if len(ps) <= 1:
        return len(ps), len(ps) == 1
    ps.sort(key=lambda p: -p.area)
    ok = len(ps) == 2 and is_handle(ps[0], ps[1], float(mesh.extents.max()))
    return len(ps), ok


def _layout_groups(part) -> int:  # noqa: ANN001
    """Groups of touching pieces of a box-layout part, its bar handle's solids aside."""
    ps = pieces(part.mesh)
    bar = [p for p in ps if len(p.faces) <= 200 and np.allclose(
        p.visual.vertex_colors[:, :3], [60, 60, 60]
    )]  # fmt: skip
    rest = [p for p in ps if not any(p is b for b in bar)]
    if not rest:
        return 0
    return len(groups(rest, TOUCH * float(part.mesh.extents.max())))


def measure(obj: ArticulatedObject, occupancy: np.ndarray) -> dict[str, Any]:
    """Piece counts and closedness of an assembled PAct object (slot k = name suffix)."""
    movable = []
    for p in obj.parts[1:]:
        n, ok = _one_piece(p.mesh)
        movable.append({"part": p.name, "pieces": n, "one_piece": ok})
    _, comps = ndimage.label(occupancy[0], structure=np.ones((3, 3, 3), bool))
    closed = [all(is_closed(x) for x in pieces(p.mesh)) for p in obj.parts]
    return {
        "movable": movable,
        "base_pieces": len(pieces(obj.parts[0].mesh)),
        "base_occupancy_components": int(comps),
        "closed_parts": int(sum(closed)),
        "parts": len(obj.parts),
    }


def _metrics(pred: ArticulatedObject, gt: ArticulatedObject) -> dict[str, float | None]:
    try:
        s = evaluate_pair(pred, gt)
    except (ValueError, MetricError) as e:
        print(f"metrics failed: {e}", file=sys.stderr)
        return {}
    return {k: (None if v is None or np.isnan(v) else float(v)) for k, v in s.items()}


def run_one(gen, img, mask, hints, gt=None) -> dict[str, Any]:  # noqa: ANN001
    t0 = time.perf_counter()
    run = gen.run(img, mask, alpha=hints.get("alpha"))
    shared = time.perf_counter() - t0 - run.timings.get("mesh", 0.0)
    out: dict[str, Any] = {"shared_s": shared}
    raw_obj = None
    for mode in MODES:
        t = time.perf_counter()
        gen.clean_geometry = mode == "clean"
        run.meshes = gen.mesh_parts(run)
        mesh_s = time.perf_counter() - t
        obj = gen.assemble(run, hints)
        if mode == "raw":
            raw_obj = obj
            layout = fit_box_layout(obj)
        else:  # as generate: the raw meshes' layout, the clean meshes as visuals
            layout = with_visuals(fit_box_layout(raw_obj), raw_obj, obj)
        total = shared + time.perf_counter() - t
        row = measure(obj, run.occupancy)
        row["mesh_s"] = mesh_s
        row["seconds"] = total
        row["layout_movable_one_group"] = [_layout_groups(p) == 1 for p in layout.parts[1:]]
        if gt is not None:
            row["metrics_assemble"] = _metrics(obj, gt)
            row["metrics_layout"] = _metrics(layout, gt)
        out[mode] = row
    gen.clean_geometry = True
    return out


def summarize(rows: dict[str, dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {"objects": len(rows)}
    for mode in MODES:
        r = [v[mode] for v in rows.values()]
        mov = [m for x in r for m in x["movable"]]
        lay = [g for x in r for g in x["layout_movable_one_group"]]
        s: dict[str, Any] = {
            "movable_parts": len(mov),
            "movable_one_piece_share": float(np.mean([m["one_piece"] for m in mov]))
            if mov
            else None,
            "movable_pieces_mean": float(np.mean([m["pieces"] for m in mov])) if mov else None,
            "movable_pieces_max": int(max(m["pieces"] for m in mov)) if mov else None,
            "base_pieces_mean": float(np.mean([x["base_pieces"] for x in r])),
            "base_pieces_le_components_share": float(
                np.mean([x["base_pieces"] <= x["base_occupancy_components"] for x in r])
            ),
            "closed_part_share": sum(x["closed_parts"] for x in r) / sum(x["parts"] for x in r),
            "layout_movable_one_group_share": float(np.mean(lay)) if lay else None,
            "seconds_per_object_median": statistics.median(x["seconds"] for x in r),
            "mesh_seconds_per_object_median": statistics.median(x["mesh_s"] for x in r),
        }
        for key in ("metrics_assemble", "metrics_layout"):
            ms = [x[key] for x in r if x.get(key)]
            if ms:
                s[key] = {
                    k: float(np.mean([m[k] for m in ms if m.get(k) is not None]))
                    for k in METRIC_KEYS
                    if any(m.get(k) is not None for m in ms)
                }
        out[mode] = s
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--examples", type=Path, default=Path("examples/images"))
    ap.add_argument("--no-examples", action="store_true")
    ap.add_argument("--split-dir", type=Path, default=Path("runs/test_split"))
    ap.add_argument("--per-category", type=int, default=6, help="test split; 0: none")
    ap.add_argument("--real", type=int, default=0, help="first N product photos of the real split")
    ap.add_argument("--real-dir", type=Path, default=None)
    ap.add_argument("--limit", type=int, default=None, help="at most N inputs per source")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)

    from generator.pact.inference.generate import PActGenerator

    gen = PActGenerator.default()
    sources: dict[str, list[tuple[str, Path, Any]]] = {}
    if not args.no_examples:
        ids = sorted(p.stem for p in args.examples.glob("*.png") if not p.stem.endswith(".mask"))
        sources["examples"] = [(i, args.examples, None) for i in ids[: args.limit]]
    if args.per_category > 0:
        from generator.data.test_split import write_test_split

        ids = write_test_split(args.split_dir, args.per_category)[: args.limit]
        sources["test_split"] = [
            (i, args.split_dir / "images", args.split_dir / "gt" / i) for i in ids
        ]
    if args.real:
        from generator.data.real_split import DEFAULT_REAL_SPLIT, read_manifest

        real = args.real_dir or Path(DEFAULT_REAL_SPLIT)
        images = [
            im for im in (read_manifest(real) or {}).get("images", []) if im["style"] == "product"
        ]
        sources["real_product"] = [
            (im["id"], real / "images", real / "gt" / im["object"]) for im in images[: args.real]
        ]
    result: dict[str, Any] = {}
    for name, items in sources.items():
        rows: dict[str, dict[str, Any]] = {}
        for iid, folder, gt_dir in items:
            img, mask, hints = _read(folder, iid)
            hints.pop("category", None)  # as bench/gen_quality.py: no category hint
            gt = load_bundle(gt_dir) if gt_dir is not None else None
            rows[iid] = run_one(gen, img, mask, hints, gt)
            c, r = rows[iid]["clean"], rows[iid]["raw"]
            print(
                f"{name} {iid}: movable pieces raw {[m['pieces'] for m in r['movable']]} "
                f"clean {[m['pieces'] for m in c['movable']]}; base raw {r['base_pieces']} "
                f"clean {c['base_pieces']} / {c['base_occupancy_components']} components; "
                f"{c['seconds']:.1f} s",
                file=sys.stderr,
                flush=True,
            )
        result[name] = {"total": summarize(rows), "per_object": rows}
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
