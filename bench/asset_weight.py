"""How heavy and how clean built assets are: size on disk, visual triangles, pieces. Prints JSON.

    .venv/bin/python bench/asset_weight.py OUT [OUT ...] [--convert IMAGES --out OUT
        [--generator pact] [--visual-faces N]]

For every asset folder (a folder with ``model.urdf``) under the given folders: its size on
disk (every file), the visual triangles of each link (the meshes its URDF ``<visual>``
elements name), and the connected pieces of each link's visual counted the strict way a
reader would: the mesh loaded with trimesh, coincident vertices merged, faces joined only
through edges two faces share (``trimesh.Trimesh.split``). A base's pieces are set against
the connected components of its visual's occupancy (the mesh voxelized at 1/32 of its
size and filled): a base is "within its components" when it has no more pieces than those.

With ``--convert IMAGES`` the folder is converted first (``pact convert``, defaults) and
the conversion's wall-clock seconds are reported too. Summary: medians and maxima of size
and triangles, the share of movable parts with at most 2 pieces and of bases within their
components, and per asset the details. Counting uses trimesh and scipy only, not the
project's own mesh code.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[1]


def folder_bytes(folder: Path) -> int:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


def strict_pieces(mesh: trimesh.Trimesh) -> int:
    g = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=False)
    g.merge_vertices(merge_tex=True, merge_norm=True)
    return len(g.split(only_watertight=False))


def occupancy_components(mesh: trimesh.Trimesh, resolution: int = 32) -> int:
    pitch = float(mesh.extents.max()) / resolution
    grid = mesh.voxelized(pitch).fill().matrix
    _, n = ndimage.label(grid, structure=np.ones((3, 3, 3)))
    return int(n)


def link_visuals(folder: Path) -> dict[str, list[Path]]:
    root = ET.parse(folder / "model.urdf").getroot()
    out = {}
    for link in root.findall("link"):
        files = [m.get("filename") for v in link.findall("visual") for m in v.iter("mesh")]
        out[link.get("name")] = [folder / f for f in files if f]
    return out


def measure(folder: Path) -> dict:
    movable = {j.find("child").get("link") for j in ET.parse(folder / "model.urdf").getroot()
               .findall("joint") if j.get("type") in ("prismatic", "revolute", "continuous")}  # fmt: skip
    links = {}
    for name, files in link_visuals(folder).items():
        meshes = [trimesh.load(f, force="mesh") for f in files]
        mesh = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
        row = {
            "triangles": len(mesh.faces),
            "pieces": strict_pieces(mesh),
            "movable": name in movable,
        }
        if name not in movable:
            row["occupancy_components"] = occupancy_components(mesh)
        links[name] = row
    return {
        "id": folder.name,
        "megabytes": round(folder_bytes(folder) / 1e6, 3),
        "triangles": sum(r["triangles"] for r in links.values()),
        "links": links,
    }


def summary(rows: list[dict]) -> dict:
    mov = [r for a in rows for r in a["links"].values() if r["movable"]]
    bases = [r for a in rows for r in a["links"].values() if not r["movable"]]
    mb = [a["megabytes"] for a in rows]
    tri = [a["triangles"] for a in rows]
    return {
        "assets": len(rows),
        "megabytes": {"median": statistics.median(mb), "max": max(mb), "min": min(mb)},
        "triangles": {"median": statistics.median(tri), "max": max(tri)},
        "movable_parts": len(mov),
        "movable_at_most_2_pieces": sum(r["pieces"] <= 2 for r in mov) / max(len(mov), 1),
        "movable_pieces_median": statistics.median([r["pieces"] for r in mov]) if mov else None,
        "bases": len(bases),
        "bases_within_components": sum(r["pieces"] <= r["occupancy_components"] for r in bases)
        / max(len(bases), 1),
        "base_pieces_median": statistics.median([r["pieces"] for r in bases]) if bases else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="*", type=Path)
    ap.add_argument("--convert", type=Path, help="Convert this image folder into --out first.")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--generator", default="pact")
    ap.add_argument("--visual-faces", type=int)
    args = ap.parse_args()
    result: dict = {}
    folders = list(args.folders)
    if args.convert is not None:
        if args.out is None:
            ap.error("--convert needs --out")
        cmd = [sys.executable, "-m", "pact_cli.main", "convert", str(args.convert),
               "--out", str(args.out), "--generator", args.generator, "--quiet"]  # fmt: skip
        if args.visual_faces is not None:
            cmd += ["--visual-faces", str(args.visual_faces)]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, check=False)
        result["convert"] = {"seconds": round(time.perf_counter() - t0, 1), "exit": proc.returncode}
        folders.append(args.out)
    assets = sorted(
        {
            p.parent
            for f in folders
            for p in ([f / "model.urdf"] + list(f.glob("*/model.urdf")))
            if p.is_file()
        }  # fmt: skip
    )
    rows = [measure(a) for a in assets]
    if not rows:
        ap.error("no asset folder (with model.urdf) found")
    result.update({"summary": summary(rows), "assets": rows})
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
