"""``Stage1Generator``: the Generator interface on PAct stage 1 alone.

image (+ optional part mask) -> part-aware flow (``stage1.generate_parts``) -> one
occupancy grid per part -> marching cubes -> part meshes in the normalized frame
([-0.5, 0.5]^3, +x front, +z up; ``scale`` None). Slot 0 is the base, the other used slots
are movable parts. Until stage 2's articulation head exists, joints come from a simple
box rule (``estimate_joint``):

- thin in x (a front panel: x extent <= ``THIN`` x the smaller of y, z) -> door,
  revolute, opening outward (+x) by up to 90 degrees:
  taller than wide -> vertical hinge (axis z) on the panel's front edge at the side
  nearest the base's side wall; wider than tall -> bottom hinge (axis y) on its front
  bottom edge (oven, dishwasher);
- thin in z and sitting on top of the base -> lid, revolute about y on its back top edge;
- otherwise (a box deeper in x: drawer) -> prismatic along +x, range 0.8 x its depth.

Colours: a part's vertex colour is the mean image colour under that part's mask pixels
(mask id = slot + 1), else ``DEFAULT_COLOR``.

Mask ids above the model's ``max_parts`` cannot be embedded: the flow sees them as the
base. With the layout from the mask (below) they get slots of their own past the flow's,
up to ``MAX_SLOTS`` in all (a chest of 12 drawers), laid out like the others.

With a part mask, ``candidates`` samples of the flow (different noise, one batch) are
drawn per image and one is kept: among the samples whose tidied parts
(``stage1.tidy_parts``) include the most of the slots the mask shows (all of them, unless
no sample does), the one whose parts agree best with the mask when rendered
(``mask_agreement.agreement``). The mask is the user's part list and layout; a sample
that leaves one of its parts empty (the small model does for about one object in six)
or puts a drawer in the wrong row is wrong whatever its other parts look like. The kept
sample's grids are then rebuilt from a box and camera fitted to the mask
(``mask_layout.layout_from_mask``: the parts where the mask puts them on the box's front,
as deep as the sample drew them, the box as deep as the candidate whose depth explains
the mask's silhouette best; ``mask_layout=False`` turns it off). When no
box explains the mask's silhouette, instead: a part
the mask shows that the kept sample still leaves empty is carved out of the base where
the mask puts it (``mask_agreement.carve_missing``), the movable parts on the front
are relabelled after the mask (``mask_agreement.relabel_front``), and the sample's height
is fitted to the proportions of the mask's silhouette (``mask_agreement.fit_height``;
``fit_height=False`` turns it off). Without a mask, the photo's silhouette (its alpha
channel, else the silhouette U-Net's) stands in: ``candidates_without_mask`` samples are
drawn, each sample's parts are seen from the view that matches the silhouette
(``mask_agreement.sample_mask``), and the one kept has the median number of parts the
samples show (``_consensus_candidate``); its own part mask then lays it out on a box fitted to
the silhouette like a masked one (``layout_without_mask=False`` turns this off: one
sample, as drawn). With or without a mask, holes in the object's outer shell are then
filled (``stage1.close_surface``; ``close_surface=False`` turns it off), except in a
laid-out sample, closed already.
"""

from __future__ import annotations

import hashlib
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
import trimesh

from generator.articulated import ArticulatedObject, Joint, Part
from generator.box_layout import fit_box_layout
from generator.mesh_repair.cleaning import clean_parts
from generator.pact.inference.mask_agreement import (
    agreements,
    carve_missing,
    fit_height,
    relabel_front,
    sample_mask,
    sample_masks,
)
from generator.pact.inference.mask_layout import depth_ratio, layout_from_mask
from generator.pact.model.checkpoint import load_checkpoint
from generator.pact.model.flow import SamplerConfig
from generator.pact.model.preprocess import encoder_inputs, square_inputs, square_silhouette
from generator.pact.model.stage1 import (
    LatentStats,
    Stage1Config,
    close_surface,
    generate_parts,
    load_stage1,
    tidy_parts,
)

log = logging.getLogger(__name__)

WEIGHTS_DIR = Path(__file__).parents[1] / "weights"
DEFAULT_COLOR = (180, 180, 180, 255)
THIN = 0.5  # a panel's thin extent is at most this fraction of its other two
DOOR_RANGE = np.pi / 2
DRAWER_TRAVEL = 0.8  # of the drawer's depth
#: Part slots (the base included) a part mask may fill: the flow's own slots, then more
#: laid out from the mask alone (``mask_layout``), as the dataset's ``max_parts``.
MAX_SLOTS = 16


class Stage1Error(RuntimeError):
    """The stage-1 weights are missing or unreadable."""


# --- geometry ---------------------------------------------------------------------------


def occupancy_mesh(grid: np.ndarray, smooth_iterations: int = 5) -> trimesh.Trimesh | None:
    """(R, R, R) bool grid ([x, y, z], voxel centres at -0.5 + (i + 0.5) / R) -> a closed
    surface in the normalized frame, Taubin-smoothed a little; None for an empty grid."""
    from skimage.measure import marching_cubes

    if not grid.any():
        return None
    R = grid.shape[0]
    padded = np.pad(grid.astype(np.float32), 1)  # closes surfaces at the grid border
    verts, faces, _, _ = marching_cubes(padded, level=0.5)
    verts = -0.5 + (verts - 0.5) / R  # padded index -> normalized coordinate
    mesh = trimesh.Trimesh(verts, faces, process=True)
    if smooth_iterations:
        trimesh.smoothing.filter_taubin(mesh, iterations=smooth_iterations)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def estimate_joint(part: np.ndarray, base: np.ndarray) -> tuple[str, Joint]:
    """(semantic, joint) of a part from its box (2, 3) and the base's box (2, 3), both
    in the normalized frame; see the module docstring for the rule."""
    lo, hi = part
    ext = hi - lo
    centre = (lo + hi) / 2
    if ext[0] <= THIN * min(ext[1], ext[2]):  # front panel: door
        if ext[2] >= ext[1]:  # tall: vertical hinge at the side nearest a base side wall
            left = abs(lo[1] - base[0, 1]) <= abs(base[1, 1] - hi[1])
            y = lo[1] if left else hi[1]
            # the panel extends from the hinge towards +y (left hinge) or -y: choose the
            # axis sign that swings it outward (+x) for positive angles
            axis = (0.0, 0.0, -1.0) if left else (0.0, 0.0, 1.0)
            joint = Joint("revolute", (hi[0], y, centre[2]), axis, 0.0, DOOR_RANGE)
        else:  # wide: bottom hinge, drops forward
            joint = Joint("revolute", (hi[0], centre[1], lo[2]), (0.0, 1.0, 0.0), 0.0, DOOR_RANGE)
        return "door", joint
    if ext[2] <= THIN * min(ext[0], ext[1]) and lo[2] >= base[1, 2] - 0.5 * ext[2] - 0.05:
        # lid on top: hinge on the back top edge, lifts up
        joint = Joint("revolute", (lo[0], centre[1], hi[2]), (0.0, -1.0, 0.0), 0.0, DOOR_RANGE)
        return "lid", joint
    travel = max(DRAWER_TRAVEL * float(ext[0]), 1e-3)
    return "drawer", Joint("prismatic", centre, (1.0, 0.0, 0.0), 0.0, travel)


def _part_color(image: np.ndarray, mask: np.ndarray | None, mask_id: int) -> tuple[int, ...]:
    if mask is None:
        return DEFAULT_COLOR
    sel = mask == mask_id
    if not sel.any():
        return DEFAULT_COLOR
    rgb = image[sel].reshape(-1, 3).mean(axis=0)
    return (*(int(round(c)) for c in rgb), 255)


# --- the generator ----------------------------------------------------------------------


class Stage1Generator:
    """PAct stage 1 as a Generator (generator/interface.py); see the module docstring."""

    name = "pact-stage1"

    def __init__(
        self,
        models: dict[str, torch.nn.Module],
        cfg: Stage1Config,
        latent_stats: LatentStats | None = None,
        *,
        sampler: SamplerConfig | None = None,
        seed: int = 0,
        version: str = "stage1",
        device: torch.device | str = "cpu",
        box_layout: bool = True,
        candidates: int = 8,
        fit_height: bool = True,
        close_surface: bool = True,
        mask_layout: bool = True,
        layout_without_mask: bool = True,
        candidates_without_mask: int = 4,
    ) -> None:
        if candidates < 1 or candidates_without_mask < 1:
            raise ValueError(
                f"candidates must be >= 1, got {candidates} and {candidates_without_mask}"
            )
        self.box_layout = box_layout
        self.fit_height = fit_height
        self.close_surface = close_surface
        self.mask_layout = mask_layout
        self.layout_without_mask = layout_without_mask
        self.candidates_without_mask = candidates_without_mask
        self.candidates = candidates
        self.models = {k: m.to(device).eval() for k, m in models.items()}
        self.cfg = cfg
        self.latent_stats = latent_stats
        self.sampler = sampler or cfg.sampler
        self.seed = seed
        self.version = version
        self.device = torch.device(device)
        self.timings: dict[str, float] = {}

    @classmethod
    def load(cls, folder: str | Path, **kwargs: Any) -> Stage1Generator:
        """Weights from ``folder/ss_vae`` (VAE checkpoint) and ``folder/stage1``."""
        folder = Path(folder)
        if not (folder / "ss_vae").is_dir() or not (folder / "stage1").is_dir():
            raise Stage1Error(
                f"{folder}: expected ss_vae/ and stage1/ checkpoint folders; train them with "
                "`pact train-gen --stage 1` and export with generator.pact.training.train_stage1.export_weights"
            )
        device = kwargs.get("device", "cpu")
        models, cfg, stats = load_stage1(folder / "stage1", device)
        models["vae"] = load_checkpoint(folder / "ss_vae", device).eval()
        if (folder / "foreground").is_dir():  # silhouettes for mask-less inputs (preprocess.py)
            models["foreground"] = load_checkpoint(folder / "foreground", device).eval()
        digest = hashlib.sha256((folder / "stage1" / "model.safetensors").read_bytes())
        kwargs.setdefault("version", f"stage1-{folder.name}-{digest.hexdigest()[:10]}")
        return cls(models, cfg, stats, **kwargs)

    @classmethod
    def default(cls, **kwargs: Any) -> Stage1Generator:
        """The shipped small model, ``generator/pact/weights/small``."""
        return cls.load(WEIGHTS_DIR / "small", **kwargs)

    # --- stage 1 proper -----------------------------------------------------------------

    def inputs(
        self, image: np.ndarray, mask: np.ndarray | None
    ) -> tuple[torch.Tensor, torch.Tensor | None, np.ndarray, np.ndarray | None]:
        """uint8 (H, W, 3) image and (H, W) mask -> model inputs (1, 3, S, S) in [0, 1]
        and (1, S, S) ids (or None), plus the squared uint8 image and mask."""
        img, m, image, mask = square_inputs(
            image, mask, self.cfg.image_encoder.image_size, self.cfg.flow.max_parts
        )
        return img.to(self.device), None if m is None else m.to(self.device), image, mask

    def predict_parts(
        self, image: np.ndarray, mask: np.ndarray | None = None, alpha: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Part occupancies (T, R, R, R) bool and used slots (T,) bool for one image."""
        occ, exists = self.predict_parts_batch(
            [image],
            None if mask is None else [mask],
            alphas=None if alpha is None else [alpha],
        )
        return occ[0], exists[0]

    def silhouettes(self, alphas: list[np.ndarray] | None) -> torch.Tensor | None:
        """Photos' alpha channels (255 = object) -> (B, S, S) bool model-size silhouettes."""
        if alphas is None:
            return None
        S = self.cfg.image_encoder.image_size
        return torch.cat([square_silhouette(a, S) for a in alphas]).to(self.device)

    def predict_parts_batch(
        self,
        images: list[np.ndarray],
        masks: list[np.ndarray] | None = None,
        callback: Any = None,
        alphas: list[np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Several images at once (faster per image on a CPU): occupancies (B, T, R, R, R)
        bool and used slots (B, T) bool. ``masks``: one per image, or None for none;
        ``alphas``: the photos' alpha channels (silhouettes for images without masks), one
        per image, or None (the silhouette U-Net then finds the object).
        ``callback(step, t, features)`` receives each sampling step's last-block features."""
        rows = [self.inputs(im, None if masks is None else masks[i]) for i, im in enumerate(images)]
        img = torch.cat([r[0] for r in rows])  # (B, 3, S, S)
        m = None if masks is None else torch.cat([r[1] for r in rows])  # (B, S, S)
        sil = self.silhouettes(alphas)
        if m is None and sil is None and self.layout_without_mask and "foreground" in self.models:
            sil = self.models["foreground"].predict(img)  # for the layout below, too
        img, m = encoder_inputs(
            self.models["image_encoder"], img, m, self.models.get("foreground"), sil
        )
        # samples per image (module docstring): without a mask, some only if the layout
        # from the silhouette (below) will judge them
        n = self.candidates if m is not None else 1
        if m is None and sil is not None and self.layout_without_mask:
            n = self.candidates_without_mask
        if n > 1:
            img = img.repeat_interleave(n, 0)
            m = None if m is None else m.repeat_interleave(n, 0)
        steps: list[tuple[int, float, torch.Tensor]] = []
        gen = torch.Generator(device=self.device).manual_seed(self.seed)
        occ, exists = generate_parts(
            self.models,
            img,
            m,
            self.sampler,
            gen,
            latent_stats=self.latent_stats,
            callback=None if callback is None else lambda i, t, f: steps.append((i, t, f)),
        )
        occ, exists = occ.cpu().numpy(), exists.cpu().numpy()
        for b in range(len(occ)):  # disjoint parts, the mask's part list (stage1.tidy_parts)
            ids = None if m is None else np.unique(m[b].cpu().numpy())
            occ[b], exists[b] = tidy_parts(occ[b], exists[b], ids)
        keep = np.arange(len(occ))
        T = occ.shape[1]
        # per image, the slots its mask shows (the flow's model-size ids: slot = id - 1)
        shown = (
            []
            if m is None
            else [
                [int(i) - 1 for i in torch.unique(m[b * n]).tolist() if 0 < int(i) <= T]
                for b in range(len(images))
            ]
        )
        if n > 1 and masks is not None:
            keep = np.array(
                [
                    self._best_candidate(
                        occ[b * n : (b + 1) * n], exists[b * n : (b + 1) * n], shown[b], masks[b]
                    )
                    + b * n
                    for b in range(len(images))
                ]
            )
        own_masks = None  # without a mask: the kept samples' own part masks (sample_mask)
        if n > 1 and masks is None:
            sils = sil.cpu().numpy()
            own = sample_masks(occ, [sils[i // n] for i in range(len(occ))])
            keep = np.array(
                [
                    self._consensus_candidate(
                        occ[b * n : (b + 1) * n], own[b * n : (b + 1) * n], sils[b]
                    )
                    + b * n
                    for b in range(len(images))
                ]
            )
            own_masks = [own[k] for k in keep]
        # every candidate's depth over width: the box layout picks the one that explains the
        # mask's silhouette best (mask_layout.layout_from_mask)
        depths = [[depth_ratio(o) for o in occ[b * n : (b + 1) * n]] for b in range(len(images))]
        depths = [[d for d in ds if d is not None] for ds in depths]
        for i, t, f in steps:
            callback(i, t, f[torch.as_tensor(keep, device=f.device)])
        occ, exists = occ[keep], exists[keep]
        if masks is not None and self.mask_layout:
            # parts past the model's slots (a chest of many drawers): slots of their own,
            # laid out from the mask like the others (the flow drew them as the base)
            top = min(max(int(np.max(mk)) for mk in masks) - 1, MAX_SLOTS - 1)
            if top >= T:
                grown = np.zeros((len(occ), top + 1, *occ.shape[2:]), bool)
                grown[:, :T] = occ
                occ, exists = grown, np.pad(exists, ((0, 0), (0, top + 1 - T)))
                for b, mk in enumerate(masks):
                    shown[b] += [int(i) - 1 for i in np.unique(mk) if T < int(i) <= top + 1]
                T = top + 1
        boxed = np.zeros(len(occ), bool)  # laid out on a box (mask_layout): closed already
        for b, slots in enumerate(shown):
            laid = (
                layout_from_mask(occ[b], masks[b], slots, depths=depths[b], image=images[b])
                if self.mask_layout
                else None
            )
            if laid is not None:  # a box and camera fitted to the mask: parts where it puts them
                occ[b] = laid[0]
                exists[b] = occ[b].reshape(T, -1).any(axis=1)
                boxed[b] = True
                continue
            if not exists[b, slots].all():  # parts the mask shows, left empty: carved
                occ[b] = carve_missing(occ[b], masks[b], slots)
            occ[b] = relabel_front(occ[b], masks[b], slots)  # the front after the mask
            ids = np.array([0, 1, *[k + 1 for k in slots]])
            occ[b], exists[b] = tidy_parts(occ[b], occ[b].reshape(T, -1).any(axis=1), ids)
            if self.fit_height:  # the proportions of the mask's silhouette
                occ[b], _ = fit_height(occ[b], masks[b])
                exists[b] = occ[b].reshape(T, -1).any(axis=1)
        if masks is None and self.layout_without_mask and sil is not None:
            # no mask: the sample's own parts, seen from the view that matches the
            # photo's silhouette, stand in for one (mask_agreement.sample_mask); the
            # object is then laid out on a box fitted to the silhouette like a masked one
            # (with the sample's depth: a mask drawn from the sample follows its depth)
            for b in range(len(occ)):
                own = own_masks[b] if own_masks else sample_mask(occ[b], sil[b].cpu().numpy())
                slots = [int(i) - 1 for i in np.unique(own) if 1 < int(i) <= T]
                laid = layout_from_mask(occ[b], own, slots, fit_depth=False) if slots else None
                if laid is not None:
                    occ[b] = laid[0]
                    exists[b] = occ[b].reshape(T, -1).any(axis=1)
                    boxed[b] = True
        if self.close_surface:  # holes in the outer shell, with or without a mask
            for b in np.flatnonzero(~boxed):
                occ[b] = close_surface(occ[b])
                exists[b] = occ[b].reshape(T, -1).any(axis=1)
        return occ, exists

    @staticmethod
    def _consensus_candidate(occ: np.ndarray, own: list[np.ndarray], silhouette: np.ndarray) -> int:
        """Index of the candidate to keep without a mask: the movable parts each sample
        shows in its own part mask ``own`` (``mask_agreement.sample_mask`` against the
        photo's ``silhouette``) are counted; among the candidates with the median count
        (the lower of the middle two; of those that show a part at all, when any does) the
        one whose silhouette agrees best with the photo's. A single sample of the small
        model often draws parts that are not there (a one-door washer with four): the
        count the samples agree on is the better guess, and of two the smaller (on the
        real dev split's product photos without masks RS-dgIoU 1.327 against 1.331 for
        the most common count; the procedural test split's are equal)."""
        sil = np.asarray(silhouette, bool)
        counts = np.array([int((np.unique(m) > 1).sum()) for m in own], dtype=np.int64)
        shown = np.sort(counts[counts > 0]) if (counts > 0).any() else counts  # something moves
        median = int(shown[(len(shown) - 1) // 2])
        best = np.flatnonzero(counts == median)
        if len(best) == 1:
            return int(best[0])
        scores = agreements([occ[c].any(axis=0)[None] for c in best], sil.astype(np.int64))
        return int(best[int(np.argmax(scores))])

    @staticmethod
    def _best_candidate(
        occ: np.ndarray, exists: np.ndarray, slots: list[int], mask: np.ndarray
    ) -> int:
        """Index of the candidate to keep (module docstring): ``occ`` (n, T, R, R, R) and
        ``exists`` (n, T) tidied candidates, ``slots`` those the mask shows, ``mask`` the
        input's part mask (H, W)."""
        realized = exists[:, slots].sum(axis=1)
        best = np.flatnonzero(realized == realized.max())
        if len(best) == 1:
            return int(best[0])
        scores = agreements([occ[c] for c in best], mask)
        return int(best[int(np.argmax(scores))])

    # --- Generator interface ------------------------------------------------------------

    def generate(
        self,
        image: np.ndarray,
        mask: np.ndarray | None = None,
        hints: dict[str, Any] | None = None,
    ) -> ArticulatedObject:
        t0 = time.perf_counter()
        occ, _ = self.predict_parts(image, mask, (hints or {}).get("alpha"))
        t1 = time.perf_counter()
        obj = self.assemble(occ, image, mask, hints)
        if self.box_layout:  # box collision geometry, consistent joints (generator.box_layout)
            obj = fit_box_layout(obj)
        self.timings = {"stage1": t1 - t0, "mesh": time.perf_counter() - t1}
        return obj

    def assemble(
        self,
        occ: np.ndarray,
        image: np.ndarray,
        mask: np.ndarray | None = None,
        hints: dict[str, Any] | None = None,
    ) -> ArticulatedObject:
        """Part occupancies (T, R, R, R) -> a valid ArticulatedObject (meshes, colours,
        box-rule joints); ``image``/``mask`` only give the colours."""
        hints = hints or {}
        _, _, sq_image, sq_mask = self.inputs(image, mask)
        meshes: dict[int, trimesh.Trimesh] = {}
        for k in range(len(occ)):
            mesh = occupancy_mesh(occ[k])
            if mesh is not None and len(mesh.faces):
                color = _part_color(sq_image, sq_mask, k + 1)
                mesh.visual.vertex_colors = np.tile(color, (len(mesh.vertices), 1))
                meshes[k] = mesh
        if 0 not in meshes:  # no base predicted: the union of everything, else a cube
            grid = occ.any(axis=0)
            meshes[0] = occupancy_mesh(grid) if grid.any() else trimesh.creation.box((1, 1, 1))
            for k in list(meshes):
                if k:
                    meshes.pop(k)
            meshes[0].visual.vertex_colors = np.tile(DEFAULT_COLOR, (len(meshes[0].vertices), 1))
        base_box = meshes[0].bounds
        parts = [Part("base", "base", meshes[0])]
        for k in sorted(meshes):
            if k == 0:
                continue
            semantic, joint = estimate_joint(meshes[k].bounds, base_box)
            parts.append(Part(f"{semantic}_{k}", semantic, meshes[k], joint))
        obj = ArticulatedObject(
            parts,
            category=str(hints.get("category", "unknown")),
            scale=None,
            provenance={
                "generator": self.name,
                "generator_version": self.version,
                "seed": self.seed,
                "mask_parts": None if mask is None else int(len(np.unique(mask)) - 1),
                "articulation": "box rule (stage1_generator.estimate_joint)",
            },
        )
        obj = clean_parts(obj)  # every generator's output: one closed piece per part
        obj.validate(f"{self.name} output")
        return obj
