"""Retrieval baseline: the nearest procedural object, fitted to the image and mask.

The kind of peer PAct is measured against (SINGAPO, URDFormer and Articulate-Anything
retrieve parts or templates). Given an image and an optional part mask:

1. Embed the image: the object's crop (the mask's or the alpha's bounding box, else
   the whole image) resized to 32x32; the embedding concatenates its grey-level
   gradient magnitudes (16x16, shape and panel layout), its colours (8x8x3, mean and
   contrast normalized) and the crop's aspect ratio. Weights are fixed
   (``EMBED_WEIGHTS``); embeddings are L2-normalized.
2. Describe the mask's part layout: the movable parts' boxes in crop coordinates.
3. Pick the nearest entry of a procedural library (rendered views of procedural
   objects, ``RetrievalLibrary``): among entries with the mask's movable-part count
   when a mask is given (else any), the smallest embedding distance plus, with a mask,
   the Hungarian-matched layout distance; a ``category`` hint restricts the library.
4. Fit: regenerate the library object (procedural factory, same seed), keep the
   movable parts matched to the mask's parts in mask-id order (unmatched library parts
   are merged into the base as static geometry), scale it along y so the crop's
   aspect ratio matches the query's (clamped to [0.75, 1.33]), and scale it uniformly
   to a ``height`` hint when one is given.

The library is built by :meth:`RetrievalLibrary.build` (rendered with the dataset
renderer, ``generator.data``) and cached on disk; ``RetrievalGenerator.default()``
builds or loads the default one.
"""

from __future__ import annotations

import hashlib
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from PIL import Image
from scipy.optimize import linear_sum_assignment

from generator.articulated import ArticulatedObject, Handle, Joint, Part, Primitive
from generator.atomic_files import atomic_write_bytes
from generator.mesh_repair.cleaning import clean_parts

log = logging.getLogger(__name__)

EMBED_SIZE = 32
EMBED_WEIGHTS = {"grad": 1.0, "colour": 0.5, "aspect": 0.5}
LAYOUT_WEIGHT = 1.0
ASPECT_CLAMP = (0.75, 1.33)
MAX_LAYOUT_PARTS = 15
LIBRARY_VERSION = 1


# --------------------------------------------------------------------------- features


def object_crop_box(
    image_shape: tuple[int, ...], mask: np.ndarray | None, alpha: np.ndarray | None
) -> tuple[int, int, int, int]:
    """(row0, row1, col0, col1) of the object: the mask's or alpha's box, else the image."""
    h, w = image_shape[:2]
    for sil in (mask, alpha):
        if sil is not None and (sil > 0).any():
            rows = np.flatnonzero((sil > 0).any(1))
            cols = np.flatnonzero((sil > 0).any(0))
            return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    return 0, h, 0, w


def embed_image(image: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """(D,) float32 unit embedding of ``image`` (H, W, 3) uint8 within ``box``."""
    r0, r1, c0, c1 = box
    crop = Image.fromarray(np.ascontiguousarray(image[r0:r1, c0:c1, :3]))
    small = np.asarray(crop.resize((EMBED_SIZE, EMBED_SIZE), Image.BILINEAR), np.float32) / 255.0
    grey = small.mean(-1)
    gy, gx = np.gradient(grey)
    grad = np.sqrt(gx**2 + gy**2).reshape(16, 2, 16, 2).mean((1, 3)).ravel()
    grad = grad / (np.linalg.norm(grad) + 1e-6)
    colour = small.reshape(8, 4, 8, 4, 3).mean((1, 3)).ravel()
    colour = (colour - colour.mean()) / (colour.std() + 1e-6) / np.sqrt(colour.size)
    aspect = np.array([np.log((c1 - c0) / max(r1 - r0, 1))], np.float32)
    v = np.concatenate(
        [
            EMBED_WEIGHTS["grad"] * grad,
            EMBED_WEIGHTS["colour"] * colour,
            EMBED_WEIGHTS["aspect"] * aspect,
        ]
    ).astype(np.float32)
    return v / (np.linalg.norm(v) + 1e-6)


def mask_layout(mask: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """(K, 4) boxes [cx, cy, w, h] of movable parts (ids 2..) in crop-relative units.

    Row k is mask id k + 2; a missing id gets NaNs.
    """
    r0, r1, c0, c1 = box
    h, w = max(r1 - r0, 1), max(c1 - c0, 1)
    k = int(mask.max()) - 1 if mask.size else 0
    out = np.full((max(k, 0), 4), np.nan, np.float32)
    for i in range(max(k, 0)):
        ys, xs = np.nonzero(mask == i + 2)
        if len(xs) == 0:
            continue
        x0, x1 = (xs.min() - c0) / w, (xs.max() + 1 - c0) / w
        y0, y1 = (ys.min() - r0) / h, (ys.max() + 1 - r0) / h
        out[i] = [(x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0]
    return out


def layout_cost(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """Hungarian match of two layouts (K, 4); returns (mean L1 cost, col index per row of a)."""
    if len(a) == 0 or len(b) == 0:
        return (0.0 if len(a) == len(b) else 1.0), np.full(len(a), -1)
    A, B = np.nan_to_num(a, nan=0.5), np.nan_to_num(b, nan=0.5)
    cost = np.abs(A[:, None, :] - B[None, :, :]).sum(-1)
    rows, cols = linear_sum_assignment(cost)
    match = np.full(len(a), -1)
    match[rows] = cols
    unmatched = abs(len(a) - len(b))
    return float((cost[rows, cols].sum() + 2.0 * unmatched) / max(len(a), len(b))), match


# --------------------------------------------------------------------------- library


@dataclass
class RetrievalLibrary:
    """Embeddings and mask layouts of rendered views of procedural objects.

    ``categories``/``seeds``/``splits`` (N,) say how to regenerate entry i's object;
    ``embed_crop`` (N, D) embeds the object crop, ``embed_full`` (N, D) the whole
    frame; ``layouts`` (N, MAX_LAYOUT_PARTS, 4) hold mask layouts padded with NaN and
    ``part_counts`` (N,) the number of movable parts; ``aspects`` (N,) the crop's
    width / height.
    """

    categories: np.ndarray
    seeds: np.ndarray
    splits: np.ndarray
    embed_crop: np.ndarray
    embed_full: np.ndarray
    layouts: np.ndarray
    part_counts: np.ndarray
    aspects: np.ndarray

    def save(self, path: str | Path) -> None:
        import io

        buf = io.BytesIO()
        np.savez_compressed(buf, version=LIBRARY_VERSION, **self.__dict__)
        atomic_write_bytes(Path(path), buf.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> RetrievalLibrary:
        with np.load(path, allow_pickle=False) as z:
            if int(z["version"]) != LIBRARY_VERSION:
                raise ValueError(
                    f"{path}: retrieval library version {int(z['version'])} != {LIBRARY_VERSION}"
                )
            return cls(**{k: z[k] for k in cls.__dataclass_fields__})

    @classmethod
    def build(
        cls,
        per_category: int = 24,
        views: int = 2,
        seed: int = 0,
        categories: tuple[str, ...] | None = None,
        image_size: int = 128,
    ) -> RetrievalLibrary:
        """Render ``views`` random views of ``per_category`` train-split objects per category."""
        from generator.data.render import ObjectRenderer, ViewConfig, sample_view
        from generator.procedural import CATEGORIES, sample_object

        cats, seeds, crops, fulls, layouts, counts, aspects = [], [], [], [], [], [], []
        for cat in categories or CATEGORIES:
            for k in range(per_category):
                obj_seed = seed + k
                obj = sample_object(cat, obj_seed)
                rng = np.random.default_rng([seed, k, sum(map(ord, cat))])
                with ObjectRenderer(obj, image_size, rng) as renderer:
                    for _ in range(views):
                        view = sample_view(obj, rng, image_size, ViewConfig(open_fraction=0.0))
                        rv = renderer.render(view)
                        box = object_crop_box(rv.rgb.shape, rv.mask, None)
                        lay = np.full((MAX_LAYOUT_PARTS, 4), np.nan, np.float32)
                        ml = mask_layout(rv.mask, box)[:MAX_LAYOUT_PARTS]
                        lay[: len(ml)] = ml
                        cats.append(cat)
                        seeds.append(obj_seed)
                        crops.append(embed_image(rv.rgb, box))
                        fulls.append(embed_image(rv.rgb, (0, image_size, 0, image_size)))
                        layouts.append(lay)
                        counts.append(len(obj.movable_parts))
                        aspects.append((box[3] - box[2]) / max(box[1] - box[0], 1))
        return cls(
            categories=np.array(cats),
            seeds=np.array(seeds, np.int64),
            splits=np.array(["train"] * len(cats)),
            embed_crop=np.stack(crops),
            embed_full=np.stack(fulls),
            layouts=np.stack(layouts),
            part_counts=np.array(counts, np.int16),
            aspects=np.array(aspects, np.float32),
        )


#: The library shipped with the project (``python -m generator.retrieval`` rebuilds it).
SHIPPED_LIBRARY = Path(__file__).parent / "assets" / f"retrieval-library-v{LIBRARY_VERSION}.npz"


def default_library_path() -> Path:
    """The shipped library when present, else a cached one under ``$PACT_CACHE_DIR``."""
    if SHIPPED_LIBRARY.is_file():
        return SHIPPED_LIBRARY
    root = Path(os.environ.get("PACT_CACHE_DIR", Path.home() / ".cache" / "pact"))
    return root / "retrieval" / f"library-v{LIBRARY_VERSION}.npz"


# --------------------------------------------------------------------------- fitting


def _scale_primitive(prim: Primitive, S: np.ndarray) -> Primitive:
    """``prim`` under the diagonal scaling ``S`` (3,) of the object frame (axis-aligned parts)."""
    R = prim.transform[:3, :3]
    local = np.abs(R.T @ np.diag(S) @ R)  # per local axis scale (exact for axis-aligned R)
    s_local = np.diag(local)
    T = prim.transform.copy()
    T[:3, 3] = prim.transform[:3, 3] * S
    if prim.kind == "box":
        size = prim.size * s_local
    else:  # cylinder along local z: radius takes the mean of the two cross scales
        size = np.array([prim.size[0] * (s_local[0] + s_local[1]) / 2, prim.size[1] * s_local[2]])
    return Primitive(prim.kind, size, T)


def scale_object(obj: ArticulatedObject, S: np.ndarray) -> ArticulatedObject:
    """``obj`` scaled by the diagonal ``S`` (3,) about the object frame origin.

    Prismatic ranges scale with the geometry along their axis; revolute ranges do not.
    """
    S = np.asarray(S, float)
    parts = []
    for p in obj.parts:
        mesh = p.mesh.copy()
        mesh.vertices = mesh.vertices * S
        joint = None
        if p.joint is not None:
            axis = p.joint.axis
            f = 1.0
            if p.joint.type == "prismatic":
                f = float(np.linalg.norm(axis * S))
                new_axis = axis * S / f
            else:
                new_axis = axis / S
                new_axis = new_axis / np.linalg.norm(new_axis)
            joint = Joint(
                p.joint.type,
                p.joint.origin * S,
                new_axis,
                p.joint.lower * f,
                p.joint.upper * f,
                p.joint.parent,
            )
        handle = None
        if p.handle is not None:
            ax = p.handle.axis * S
            handle = Handle(p.handle.position * S, ax / np.linalg.norm(ax), p.handle.kind)
        parts.append(
            Part(
                p.name,
                p.semantic,
                mesh,
                joint,
                [_scale_primitive(q, S) for q in p.primitives],
                handle,
                p.material,
            )
        )
    return ArticulatedObject(parts, obj.category, obj.scale, dict(obj.provenance))


def mirrored_across_y(part: Part) -> Part:
    """``part`` mirrored across the middle of its box along y (a left-hinged door made a
    right-hinged one): mesh (winding flipped), primitives, handle and joint origin."""
    lo, hi = part.mesh.bounds
    c = 0.5 * (lo[1] + hi[1])
    flip = np.diag([1.0, -1.0, 1.0, 1.0])
    about = np.eye(4)
    about[1, 3] = 2.0 * c
    M = about @ flip  # y -> 2c - y
    mesh = part.mesh.copy()
    mesh.vertices = trimesh.transform_points(mesh.vertices, M)
    mesh.faces = mesh.faces[:, ::-1]
    prims = [Primitive(q.kind, q.size, M @ q.transform @ flip) for q in part.primitives]
    handle = None
    if part.handle is not None:
        h = part.handle
        handle = Handle(trimesh.transform_points([h.position], M)[0], flip[:3, :3] @ h.axis, h.kind)
    joint = part.joint
    if joint is not None:
        joint = Joint(joint.type, trimesh.transform_points([joint.origin], M)[0], -(flip[:3, :3] @ joint.axis),
                      joint.lower, joint.upper, joint.parent)  # fmt: skip
    return Part(part.name, part.semantic, mesh, joint, prims, handle, part.material)


#: Thickness of a panel made from a deeper part (a retrieved drawer that the photo shows
#: hinged), as a share of the object's largest side.
PANEL_SHARE = 0.03


def follow_motions(obj: ArticulatedObject, motions: dict[int, str]) -> ArticulatedObject:
    """``obj`` with its ``t``-th movable part moving as ``motions[t]`` says (the user's or
    the photo parser's word, :mod:`generator.motions`): a part already moving so is kept;
    a door hinged on the other side is mirrored; any other is remade as a panel for the
    motion's joint with a bar handle (:func:`generator.box_layout.rigged_panel`). A part
    to be hinged keeps only its front slab (a lid its top slab), as thick as a panel: a
    retrieved drawer's whole box swung on a hinge would sweep through the carcass. Parts
    are named after what they now are (``door_0``, ``drawer_1``, ...)."""
    from generator.box_layout import rigged_panel
    from generator.motions import MOTION_SEMANTIC, joint_for_motion, motion_of

    if not motions:
        return obj
    movable = obj.movable_parts
    outer = obj.bounds()
    replaced = {}
    for t, motion in motions.items():
        part = movable[t]
        have = motion_of(part)
        if have == motion:
            continue
        if {have, motion} == {"door_left", "door_right"}:
            new = mirrored_across_y(part)
        else:
            mesh = part.mesh if motion == "drawer" else _panel_slab(part.mesh, motion, outer)
            lo, hi = mesh.bounds
            joint = joint_for_motion(motion, lo, hi, parent=part.joint.parent)
            semantic = MOTION_SEMANTIC[motion]
            new = rigged_panel(
                Part(part.name, semantic, mesh, joint, [], None, part.material), outer
            )
        replaced[part.name] = new
    if not replaced:
        return obj
    counters: dict[str, int] = {}
    renamed = []
    for p in (replaced.get(p.name, p) for p in obj.parts):
        if p.joint is not None:  # named per semantic in order, as keep_parts names them
            k = counters.get(p.semantic, 0)
            counters[p.semantic] = k + 1
            if p.name != f"{p.semantic}_{k}":
                p = Part(f"{p.semantic}_{k}", p.semantic, p.mesh, p.joint, p.primitives,
                         p.handle, p.material)  # fmt: skip
        renamed.append(p)
    return ArticulatedObject(renamed, obj.category, obj.scale, dict(obj.provenance))


def _panel_slab(mesh: trimesh.Trimesh, motion: str, outer: np.ndarray) -> trimesh.Trimesh:
    """The front slab of ``mesh``'s box (a lid: the top slab), ``PANEL_SHARE`` of the
    object's largest side thick, in the mesh's mean colour; ``mesh`` when thinner."""
    lo, hi = (np.array(b, float) for b in mesh.bounds)
    t = PANEL_SHARE * float(np.max(np.asarray(outer)[1] - np.asarray(outer)[0]))
    k = 2 if motion == "lid" else 0
    if hi[k] - lo[k] <= t:
        return mesh
    lo[k] = hi[k] - t
    slab = trimesh.creation.box(hi - lo)
    slab.apply_translation((lo + hi) / 2)
    colours = getattr(mesh.visual, "vertex_colors", None)
    if colours is not None and len(colours):
        mean = np.asarray(colours)[:, :4].mean(axis=0).astype(np.uint8)
        slab.visual.vertex_colors = np.tile(mean, (len(slab.vertices), 1))
    return slab


def keep_parts(obj: ArticulatedObject, order: list[str]) -> ArticulatedObject:
    """Movable parts ``order`` (names, in that order, renamed per semantic) on the base.

    Every other movable part is merged into the base as static geometry.
    """
    base = obj.base
    dropped = [p for p in obj.movable_parts if p.name not in order]
    meshes = [base.mesh] + [p.mesh for p in dropped]
    prims = list(base.primitives) + [q for p in dropped for q in p.primitives]
    merged = trimesh.util.concatenate(meshes) if dropped else base.mesh
    if dropped and base.primitives and not all(p.primitives for p in dropped):
        prims = []  # mixed: let the collision stage decompose the merged mesh
    new_base = Part("base", "base", merged, None, prims, None, base.material)
    counters: dict[str, int] = {}
    parts = [new_base]
    for name in order:
        p = obj.part(name)
        k = counters.get(p.semantic, 0)
        counters[p.semantic] = k + 1
        parts.append(
            Part(
                f"{p.semantic}_{k}", p.semantic, p.mesh, p.joint, p.primitives, p.handle, p.material
            )
        )
    return ArticulatedObject(parts, obj.category, obj.scale, dict(obj.provenance))


# --------------------------------------------------------------------------- generator


class RetrievalGenerator:
    """Nearest procedural object by image embedding and mask layout (see module docstring)."""

    name = "retrieval"
    version = f"retrieval-{LIBRARY_VERSION}"

    def __init__(self, library: RetrievalLibrary):
        self.library = library
        self.timings: dict[str, float] = {}

    @classmethod
    def default(cls, path: str | Path | None = None) -> RetrievalGenerator:
        """Load the library at ``path`` (default: the cache), building it once if missing."""
        path = Path(path) if path else default_library_path()
        if not path.is_file():
            log.warning("building the retrieval library at %s (once; about a minute)", path)
            RetrievalLibrary.build().save(path)
        return cls(RetrievalLibrary.load(path))

    def retrieve(
        self, image: np.ndarray, mask: np.ndarray | None = None, hints: dict[str, Any] | None = None
    ) -> tuple[int, np.ndarray]:
        """Index of the chosen library entry and, per query movable part, the library part slot."""
        hints = hints or {}
        lib = self.library
        alpha = hints.get("alpha")
        box = object_crop_box(image.shape, mask, alpha)
        cropped = mask is not None or (alpha is not None and (np.asarray(alpha) > 0).any())
        q = embed_image(image, box)
        cand = np.ones(len(lib.categories), bool)
        cat = hints.get("category")
        if cat and cat != "unknown" and (lib.categories == cat).any():
            cand &= lib.categories == cat
        cost = np.linalg.norm((lib.embed_crop if cropped else lib.embed_full) - q, axis=1)
        layout = None
        if mask is not None:
            layout = mask_layout(mask, box)
            same = cand & (lib.part_counts == len(layout))
            if same.any():
                cand = same
            else:  # nearest part count
                diff = np.abs(lib.part_counts.astype(int) - len(layout))
                cand &= diff == diff[cand].min()
            lay_cost = np.array(
                [
                    layout_cost(layout, lib.layouts[i][~np.isnan(lib.layouts[i][:, 0])])[0]
                    if cand[i]
                    else np.inf
                    for i in range(len(cand))
                ]
            )
            cost = cost + LAYOUT_WEIGHT * lay_cost
        cost = np.where(cand, cost, np.inf)
        best = int(np.argmin(cost))
        if layout is None:
            match = np.arange(int(lib.part_counts[best]))
        else:
            lib_lay = lib.layouts[best][: int(lib.part_counts[best])]
            _, match = layout_cost(layout, lib_lay)
        return best, match

    def generate(
        self, image: np.ndarray, mask: np.ndarray | None = None, hints: dict[str, Any] | None = None
    ) -> ArticulatedObject:
        from generator.procedural import sample_object

        hints = dict(hints or {})
        t0 = time.perf_counter()
        best, match = self.retrieve(image, mask, hints)
        lib = self.library
        t1 = time.perf_counter()
        cat, seed = str(lib.categories[best]), int(lib.seeds[best])
        obj = sample_object(cat, seed, split=str(lib.splits[best]))
        movable = obj.movable_parts
        kept = [(i, int(j)) for i, j in enumerate(match) if 0 <= j < len(movable)]
        obj = keep_parts(obj, [movable[j].name for _, j in kept])
        # the motions the hints give, by mask id (query part i is mask id i + 2)
        given = {
            t: (hints.get("parts") or {}).get(str(i + 2), {}).get("motion")
            for t, (i, _) in enumerate(kept)
        }
        obj = follow_motions(obj, {t: m for t, m in given.items() if m})
        # Aspect: query crop width/height against the library view's.
        alpha = hints.get("alpha")
        box = object_crop_box(image.shape, mask, alpha)
        q_aspect = (box[3] - box[2]) / max(box[1] - box[0], 1)
        sy = float(np.clip(q_aspect / max(float(lib.aspects[best]), 1e-3), *ASPECT_CLAMP))
        S = np.array([1.0, sy, 1.0])
        height = hints.get("height")
        if height:
            S = S * float(height) / float(obj.bounds()[1, 2] - obj.bounds()[0, 2])
        obj = scale_object(obj, S)
        obj.provenance = {
            "generator": self.name,
            "generator_version": self.version,
            "retrieved": {"category": cat, "seed": seed, "entry": best},
            "mask_parts": None if mask is None else int(len(match)),
        }
        obj = clean_parts(obj)  # every generator's output (procedural parts are already clean)
        self.timings = {"retrieve": t1 - t0, "fit": time.perf_counter() - t1}
        return obj


def library_digest(lib: RetrievalLibrary) -> str:
    h = hashlib.sha256()
    for k in sorted(lib.__dict__):
        h.update(np.ascontiguousarray(getattr(lib, k)).tobytes())
    return h.hexdigest()[:12]


if __name__ == "__main__":
    # Rebuild the shipped library: python -m generator.retrieval
    logging.basicConfig(level=logging.INFO)
    t = time.perf_counter()
    lib = RetrievalLibrary.build()
    lib.save(SHIPPED_LIBRARY)
    log.info(
        "wrote %s (%d views, %.0f s)", SHIPPED_LIBRARY, len(lib.seeds), time.perf_counter() - t
    )
