"""``PActGenerator``: the full PAct chain as a Generator (generator/interface.py).

image (+ optional part mask) -> stage 1 (part-decomposed sparse structure: one R = 32
occupancy per part slot, ``Stage1Generator.predict_parts`` with the shipped stage-1
checkpoints) -> token voxels per part -> stage 2 (structure-conditioned flow, Euler + CFG,
last-block features collected by a ``FeatureAggregator`` over the last S steps) -> SLAT
decode (fine SDF + RGB per token voxel) -> marching cubes per part, the topology fixed by
the stage-1 occupancy (``slat_vae.constrain_sdf``: one closed piece per connected piece
of the part's occupancy, no islands) -> ``part_cleaning.clean_mesh`` (the cleaning every
generator's output gets) -> articulation head on the aggregated features (+ revolute
origins projected onto the part's AABB surface; ``articulation.apply_shape_prior``: no
side-hinged door as wide as a drawer, no drawer taller than wide (a door, cut to a
door's thickness by ``door_panel``), an oven's full-width door hinged at the bottom (and
a stacked oven's other doors, ``articulation.match_oven_doors``), a door off the middle
hinged at its outer edge, off with ``shape_prior=False``; slots past
the flow's, laid out from the mask, are voxel boxes
typed by ``articulation.joint_from_shape``) -> ``ArticulatedObject`` in the
normalized frame (``scale`` None; a ``height`` hint in metres
sets ``scale`` = height / the object's z extent). ``assemble`` returns that raw output
(what the benchmarks score); ``generate`` then fits the box layout
(``generator.box_layout``: box collision geometry and joints a simulator can move
without collisions; ``box_layout=False`` turns it off). ``clean_geometry=False`` gives
the raw decoded meshes (islands and fragments, for comparisons: ``bench/part_geometry.py``).

Slot 0 is the base; slots 1.. are movable parts named ``<semantic>_<slot>``. Without
stage-1 checkpoints only ``generate_from_occupancy`` (teacher forcing with given part
voxels) works; ``generate`` raises ``PActWeightsError``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
import trimesh

from generator.articulated import ArticulatedObject, Joint, Part
from generator.box_layout import fit_box_layout, robust_bounds
from generator.mesh_repair.cleaning import clean_mesh, drop_slivers, panel_and_handle, union_solids
from generator.mesh_repair.closing import slice_closed
from generator.mesh_repair.decimation import DEFAULT_VISUAL_FACES, light_object
from generator.pact.inference.sweep_clearance import keep_sweeps_apart
from generator.pact.model.articulation import (
    DOOR_HINGE,
    DOOR_PANEL_DEPTH,
    LID_PANEL_HEIGHT,
    ArticulationHead,
    PartJoint,
    aggregate_last,
    apply_category_prior,
    apply_shape_prior,
    decode_joint,
    joint_from_shape,
    joint_of_motion,
    match_oven_doors,
    pool_parts,
    pool_slots,
    postprocess_joint,
)
from generator.pact.model.checkpoint import load_checkpoint
from generator.pact.model.preprocess import encoder_inputs, square_inputs, square_silhouette
from generator.pact.model.slat_vae import decode_latents, decode_part_mesh
from generator.pact.model.stage2 import (
    Stage2Config,
    Stage2SamplerConfig,
    collate,
    config_from_dict,
    sample_stage2,
    tokenize,
    untokenize,
    voxels_from_occupancy,
)
from generator.procedural.solids import box as solid_box

log = logging.getLogger(__name__)

WEIGHTS_DIR = Path(__file__).parents[1] / "weights"
VERSION = "pact-small-1"
DEFAULT_COLOR = (180, 180, 180, 255)
#: Share of the visual triangle budget the decoded meshes get; the layout's handles and
#: drawer trays and the texture's split edges use the rest.
VISUAL_FACES_SHARE = 0.85


class PActWeightsError(FileNotFoundError):
    """Checkpoints missing; the message says which folder and how to produce it."""


@dataclass
class PActRun:
    """Everything one generation produced before assembly (for ablations).

    occupancy (K, R, R, R) bool per slot; meshes per slot (None: no surface); features_2
    per sampling step, each (L, D) (stage 2 last block); tokens' slot/valid for pooling;
    features_1 per stage-1 step (K, L1, D1) or empty (teacher forcing); decoded per slot
    the SLAT decoder's output (token coords (N, 3), sdf (N, sub^3), rgb (N, 3) uint8), so
    that ``PActGenerator.mesh_parts`` can mesh it again.
    """

    occupancy: np.ndarray
    meshes: dict[int, trimesh.Trimesh | None]
    features_2: list[torch.Tensor]
    slot: torch.Tensor
    valid: torch.Tensor
    features_1: list[torch.Tensor] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    decoded: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)


def _load_fp32(path: Path, device: str) -> torch.nn.Module:
    if not (path / "config.json").is_file():
        raise PActWeightsError(
            f"{path}: no checkpoint; train it with `python -m generator.pact.training.train_stage2`"
        )
    return load_checkpoint(path, device).float().eval()


class PActGenerator:
    """PAct (stage 1 + stage 2 + articulation head) behind the Generator interface."""

    name = "pact"

    def __init__(
        self,
        models: dict[str, torch.nn.Module],
        cfg: Stage2Config,
        stage1: Any | None = None,
        *,
        sampler: Stage2SamplerConfig | None = None,
        seed: int = 0,
        version: str = VERSION,
        device: torch.device | str = "cpu",
        stage1_head: ArticulationHead | None = None,
        box_layout: bool = True,
        clean_geometry: bool = True,
        shape_prior: bool = True,
    ) -> None:
        self.device = torch.device(device)
        self.box_layout = box_layout
        self.shape_prior = shape_prior
        self.clean_geometry = clean_geometry
        self.models = {k: m.to(self.device).eval() for k, m in models.items()}
        self.cfg = cfg
        self.stage1 = stage1
        self.stage1_head = None if stage1_head is None else stage1_head.to(self.device).eval()
        self.sampler = sampler or cfg.sampler
        self.seed = seed
        self.version = version
        self.timings: dict[str, float] = {}

    @classmethod
    def load(
        cls,
        folder: str | Path,
        device: str | None = None,
        candidates: int = 8,
        layout_without_mask: bool = True,
        **kwargs: Any,
    ) -> PActGenerator:
        """Stage 2 from ``folder/slat_vae`` and ``folder/stage2/{image_encoder,flow,head}``;
        stage 1 from ``folder/ss_vae`` + ``folder/stage1`` when present, drawing
        ``candidates`` samples per image with a part mask, and without one laid out on
        the silhouette unless ``layout_without_mask`` is False (``stage1_generator``).
        Stage 1 samples as its weights' config says (``.stage1.sampler``, a
        ``SamplerConfig``), stage 2 as ``sampler`` (a ``Stage2SamplerConfig``, default
        its defaults); both attributes may be replaced after loading."""
        folder = Path(folder)
        device = device or ("cuda" if torch.cuda.is_available() else "cpu")
        models = {"vae": _load_fp32(folder / "slat_vae", device)}
        for role in ("image_encoder", "flow", "head"):
            models[role] = _load_fp32(folder / "stage2" / role, device)
        cfg = config_from_dict(
            {
                "vae": vars(models["vae"].cfg),
                "image_encoder": {**vars(models["image_encoder"].cfg), "weights": None},
                "flow": vars(models["flow"].cfg),
                "head": vars(models["head"].cfg),
            }
        )
        stage1 = None
        if (folder / "stage1").is_dir() and (folder / "ss_vae").is_dir():
            from generator.pact.inference.stage1_generator import Stage1Generator

            stage1 = Stage1Generator.load(
                folder,
                device=device,
                seed=kwargs.get("seed", 0),
                candidates=candidates,
                layout_without_mask=layout_without_mask,
            )
        else:
            log.warning("%s: no stage-1 checkpoints; only generate_from_occupancy works", folder)
        s1_head = None
        if (folder / "stage1_head" / "config.json").is_file():
            s1_head = _load_fp32(folder / "stage1_head", device)
        digest = hashlib.sha256((folder / "stage2" / "flow" / "model.safetensors").read_bytes())
        kwargs.setdefault("version", f"{VERSION}-{digest.hexdigest()[:10]}")
        return cls(models, cfg, stage1, device=device, stage1_head=s1_head, **kwargs)

    @classmethod
    def default(cls, **kwargs: Any) -> PActGenerator:
        """The shipped small model (generator/pact/weights/small); CUDA when present."""
        return cls.load(WEIGHTS_DIR / "small", **kwargs)

    # --- the chain ------------------------------------------------------------------------

    def stage1_parts(
        self, image: np.ndarray, mask: np.ndarray | None, alpha: np.ndarray | None = None
    ) -> tuple[np.ndarray, list[torch.Tensor]]:
        """Stage 1: part occupancies (K, R, R, R) and its per-step last-block features;
        more than K (the flow's slots) when a part mask shows more parts
        (``Stage1Generator``: laid out from the mask)."""
        if self.stage1 is None:
            raise PActWeightsError(
                "stage-1 checkpoints (weights/small/ss_vae, weights/small/stage1) are missing; "
                "use generate_from_occupancy or train stage 1"
            )
        feats: list[torch.Tensor] = []
        occ, _ = self.stage1.predict_parts_batch(
            [image],
            None if mask is None else [mask],
            callback=lambda i, t, f: feats.append(f[0].float().cpu()),
            alphas=None if alpha is None else [alpha],
        )
        occ = occ[0]  # (T, R, R, R), tidied (stage1.tidy_parts); T > K: laid out from the mask
        out = np.zeros((max(self.cfg.flow.max_parts, len(occ)), *occ.shape[1:]), bool)
        out[: len(occ)] = occ
        return out, feats

    def run(
        self,
        image: np.ndarray,
        mask: np.ndarray | None = None,
        occupancy: np.ndarray | None = None,
        alpha: np.ndarray | None = None,
    ) -> PActRun:
        """Stage 1 (unless ``occupancy`` (K, R, R, R) is given), stage 2, decode.
        ``alpha``: the photo's alpha channel, the silhouette when there is no mask."""
        timings: dict[str, float] = {}
        t = time.perf_counter()
        feats1: list[torch.Tensor] = []
        if occupancy is None:
            occupancy, feats1 = self.stage1_parts(image, mask, alpha)
            timings["stage1"] = time.perf_counter() - t
        occupancy = np.asarray(occupancy, bool)
        K = self.cfg.flow.max_parts  # stage 2 draws these slots; any past them: voxel boxes
        t = time.perf_counter()
        encoder = self.models["image_encoder"]
        img, m, _, _ = square_inputs(image, mask, encoder.cfg.image_size)
        foreground = None if self.stage1 is None else self.stage1.models.get("foreground")
        sil = None if alpha is None else square_silhouette(alpha, encoder.cfg.image_size)
        with torch.no_grad():
            img, _ = encoder_inputs(encoder, img.to(self.device), m, foreground, sil)
            cond = encoder(img)  # (1, N_img, D_img)
        timings["encode"] = time.perf_counter() - t
        t = time.perf_counter()
        coords, slot = voxels_from_occupancy(occupancy[:K])
        meshes: dict[int, trimesh.Trimesh | None] = {}
        if len(coords) == 0:
            return PActRun(occupancy, {}, [], torch.zeros(1, 0), torch.zeros(1, 0), feats1, timings)
        toks = tokenize(coords, slot, occupancy[:K], self.cfg.flow)
        batch = collate([toks], max(len(toks.slot), self.cfg.flow.max_tokens)).to(self.device)
        feats2: list[torch.Tensor] = []
        gen = torch.Generator(device=self.device).manual_seed(self.seed)
        x = sample_stage2(
            self.models["flow"],
            batch,
            cond,
            self.sampler,
            gen,
            callback=lambda i, t_, f: feats2.append(f[0].float().cpu()),
        )
        timings["stage2"] = time.perf_counter() - t
        t = time.perf_counter()
        z = untokenize(x[0].float().cpu().numpy(), toks, self.cfg.flow.latent_channels)
        decoded = {}
        for k in range(len(occupancy)):
            sel = slot == k
            if not sel.any():
                continue
            occ_k = torch.from_numpy(occupancy[k])
            sdf, rgb = decode_latents(
                self.models["vae"], torch.from_numpy(coords[sel]), torch.from_numpy(z[sel]), occ_k
            )
            decoded[k] = (coords[sel], sdf, rgb)
        timings["decode"] = time.perf_counter() - t
        t = time.perf_counter()
        out = PActRun(
            occupancy,
            meshes,
            feats2,
            batch.slot[:1].cpu(),
            batch.valid[:1].cpu(),
            feats1,
            timings,
            decoded,
        )
        out.meshes = self.mesh_parts(out)
        timings["mesh"] = time.perf_counter() - t
        return out

    def mesh_parts(
        self, run: PActRun, clean: bool | None = None
    ) -> dict[int, trimesh.Trimesh | None]:
        """Per slot the part mesh of the decoded SDF (``run.decoded``): with ``clean``
        (default ``self.clean_geometry``) the stage-1 occupancy fixes its topology
        (``slat_vae.constrain_sdf``) and ``clean_mesh`` checks it (the base keeps one
        piece per connected piece of its occupancy, a movable part one piece, every
        piece closed); without, the raw marching cubes of the decoded SDF."""
        clean = self.clean_geometry if clean is None else clean
        meshes: dict[int, trimesh.Trimesh | None] = {}
        for k, (coords, sdf, rgb) in run.decoded.items():
            mesh = decode_part_mesh(coords, sdf, rgb, run.occupancy[k], constrain=clean)
            if clean and mesh is not None and len(mesh.faces):
                mesh = clean_mesh(mesh, movable=k > 0)
            meshes[k] = mesh
        return meshes

    def articulation_source(self, run: PActRun, source: str | None = None) -> str:
        """The joint source ``articulation`` uses for ``run``: ``source`` if given, else
        ``"stage2+types1"`` when the stage-1 head and the run's stage-1 features exist,
        else ``"stage2"``."""
        if source is not None:
            return source
        if self.stage1_head is not None and run.features_1 and run.features_2:
            return "stage2+types1"
        return "stage2"

    def articulation(
        self, run: PActRun, agg_steps: int | None = None, source: str | None = None
    ) -> list[Any]:
        """Per slot (index k) the decoded joint (``PartJoint``) or None, from the last
        ``agg_steps`` steps' features of stage 2 (``"stage2"``, the paper's head) or
        stage 1 (``"stage1"``), or (``"stage2+types1"``, the default when the stage-1
        head is there) stage 2's joint unless the stage-1 head reads the part as another
        joint type, then the stage-1 head's joint: on real photos stage 2 often takes a
        drawer the mask relabelled (``mask_agreement.relabel_front``), a panel a voxel
        or two deep, for a door (21 of the 102 parts of 70 of the real dev split's
        product photos of the wrong type, against 13; 12 against 9 of the test split's
        96)."""
        source = self.articulation_source(run, source)
        if source == "stage2+types1":
            j2 = self.articulation(run, agg_steps, "stage2")
            j1 = self.articulation(run, agg_steps, "stage1")
            return [
                a if a is None or k >= len(j1) or j1[k] is None or j1[k].type == a.type else j1[k]
                for k, a in enumerate(j2)
            ]
        S = agg_steps or self.sampler.agg_steps
        K = self.cfg.flow.max_parts
        with torch.no_grad():
            if source == "stage2":
                if not run.features_2:
                    return [None] * K
                H = aggregate_last(run.features_2, S)[None].to(self.device)  # (1, L, D)
                pooled, present = pool_parts(
                    H, run.slot.to(self.device), run.valid.to(self.device), K
                )
                out = self.models["head"](pooled)
            else:
                if self.stage1_head is None or not run.features_1:
                    raise PActWeightsError("no stage-1 articulation head / stage-1 features")
                H = aggregate_last(run.features_1, S)[None].to(self.device)  # (1, K1, L1, D1)
                pooled = pool_slots(H)[:, :K]
                present = torch.ones(pooled.shape[:2], dtype=torch.bool, device=self.device)
                out = self.stage1_head(pooled)
        return [
            decode_joint(out, (0, k)) if bool(present[0, k]) else None
            for k in range(pooled.shape[1])
        ]

    def assemble(
        self,
        run: PActRun,
        hints: dict[str, Any] | None = None,
        agg_steps: int | None = None,
        source: str | None = None,
    ) -> ArticulatedObject:
        """Meshes + articulation (post-processed) -> ArticulatedObject; ``source`` as
        ``articulation``."""
        hints = hints or {}
        t = time.perf_counter()
        source = self.articulation_source(run, source)
        joints = self.articulation(run, agg_steps, source)
        meshes = {k: m for k, m in run.meshes.items() if m is not None and len(m.faces)}
        for k in range(len(run.occupancy)):  # parts without a surface: their voxel box
            if k not in meshes and run.occupancy[k].any():
                idx = np.argwhere(run.occupancy[k])
                lo, hi = -0.5 + idx.min(0) / 32.0, -0.5 + (idx.max(0) + 1) / 32.0
                box = trimesh.creation.box(hi - lo)
                box.apply_translation((lo + hi) / 2)
                box.visual.vertex_colors = np.tile(DEFAULT_COLOR, (len(box.vertices), 1))
                meshes[k] = box
        if 0 not in meshes:
            base = trimesh.creation.box((1.0, 1.0, 1.0))
            base.visual.vertex_colors = np.tile(DEFAULT_COLOR, (len(base.vertices), 1))
            meshes = {0: base}
        parts = [Part("base", "base", meshes[0])]
        part_bounds = np.array([m.bounds for m in meshes.values()])
        obj_lo, obj_hi = part_bounds[:, 0].min(0), part_bounds[:, 1].max(0)
        shape_prior = self.shape_prior and hints.get("category") not in DOOR_HINGE
        motions = given_motions(hints)  # slot -> the user's or the photo parser's motion
        read: dict[int, tuple[PartJoint, np.ndarray, np.ndarray]] = {}  # k -> joint, lo, hi
        for k in sorted(meshes):
            if k == 0:
                continue
            lo, hi = meshes[k].bounds
            if k < len(joints):
                pj = joints[k]
            else:  # past the flow's slots (laid out from the mask): no head read it
                pj = joint_from_shape(lo, hi, obj_lo, obj_hi)
            if k in motions:  # how the part moves is given: type, hinge edge, direction
                drawn = (pj.type, pj.semantic) if pj is not None else ("prismatic", "drawer")
                pj = joint_of_motion(motions[k], lo, hi, pj)
                if pj.type == "revolute" and (drawn[0] == "prismatic" or drawn[1] == "lid"):
                    if motions[k] == "lid":  # a lid is the top of what was drawn
                        height = LID_PANEL_HEIGHT * (obj_hi[2] - obj_lo[2])
                        meshes[k] = lid_panel(meshes[k], height)
                    else:
                        depth = DOOR_PANEL_DEPTH * (obj_hi[0] - obj_lo[0])
                        meshes[k] = door_panel(meshes[k], depth)
                read[k] = (pj, lo, hi)
                continue
            if pj is None:
                continue
            if shape_prior:
                # no side-hinged door as wide as a drawer, no drawer taller than wide, a
                # door off the middle hinged at its outer edge (an appliance the user
                # names: its category's rule knows)
                drawn = pj.type, pj.semantic
                pj = apply_shape_prior(pj, lo, hi, obj_lo, obj_hi)
                front_door = pj.type == "revolute" and pj.semantic == "door"
                if front_door and (drawn[0] == "prismatic" or drawn[1] == "lid"):
                    # drawn as deep as a drawer, or as a lid reaching far back
                    meshes[k] = door_panel(meshes[k], DOOR_PANEL_DEPTH * (obj_hi[0] - obj_lo[0]))
            read[k] = (pj, lo, hi)
        guessed = {k: v for k, v in read.items() if k not in motions}
        if shape_prior and guessed:  # a stacked oven's doors all swing down
            matched = match_oven_doors(
                [v[0] for v in guessed.values()], [v[1:] for v in guessed.values()], obj_lo, obj_hi
            )
            read.update(
                {k: (j, *v[1:]) for (k, v), j in zip(guessed.items(), matched, strict=True)}
            )
        for k in sorted(meshes):
            if k == 0:
                continue
            if k not in read:
                parts.append(Part(f"part_{k}", "drawer", meshes[k], Joint("fixed")))
                continue
            pj, lo, hi = read[k]
            if hints.get("category") and k not in motions:  # the category: how doors hinge
                pj = apply_category_prior(pj, str(hints["category"]), lo, hi, obj_hi[0])
            pj = postprocess_joint(pj, lo, hi)
            if pj.type == "fixed":
                joint = Joint("fixed", origin=pj.origin, axis=pj.axis)
            else:
                joint = Joint(pj.type, pj.origin, pj.axis, pj.lower, pj.upper)
            parts.append(Part(f"{pj.semantic}_{k}", pj.semantic, meshes[k], joint))
        scale = None
        if hints.get("height"):
            b = np.array([p.mesh.bounds for p in parts])
            scale = float(hints["height"]) / float(b[:, 1, 2].max() - b[:, 0, 2].min())
        obj = ArticulatedObject(
            parts,
            category=str(hints.get("category", "unknown")),
            scale=scale,
            provenance={
                "generator": self.name,
                "generator_version": self.version,
                "seed": self.seed,
                "articulation_features": source,
                "agg_steps": agg_steps or self.sampler.agg_steps,
                "geometry": "occupancy-constrained" if self.clean_geometry else "raw",
            },
        )
        obj.validate(f"{self.name} output")
        self.timings = {**run.timings, "articulation": time.perf_counter() - t}
        return obj

    # --- Generator interface --------------------------------------------------------------

    def generate(
        self,
        image: np.ndarray,
        mask: np.ndarray | None = None,
        hints: dict[str, Any] | None = None,
    ) -> ArticulatedObject:
        hints = hints or {}
        run = self.run(image, mask, alpha=hints.get("alpha"))
        # the visuals within their triangle budget from the start: the cuts, the photo's
        # texture and the build then work on light meshes (the layout reads the raw ones)
        obj = light_object(self.assemble(run, hints), self.visual_faces(hints))
        if not self.box_layout:
            return obj
        if not self.clean_geometry:
            return fit_box_layout(obj)
        # collision boxes, joints and handles from the raw decoded meshes (the layout's
        # rules were fitted to those: from the clean meshes 2 of the 42 test cabinets fail
        # validation), the clean meshes as the visuals
        raw_meshes = self.mesh_parts(run, clean=False)
        for k, mesh in run.meshes.items():
            if k > 0 and _raw_face_lost(raw_meshes.get(k), mesh):
                raw_meshes[k] = mesh
        raw = self.assemble(dataclasses.replace(run, meshes=raw_meshes), hints)
        return with_visuals(fit_box_layout(raw), raw, obj)

    @staticmethod
    def visual_faces(hints: dict[str, Any]) -> int:
        """Triangles the visuals may hold in all: ``hints["visual_faces"]`` (0: all), else
        ``DEFAULT_VISUAL_FACES``; the handles and trays the layout adds come on top, and
        stay within the rest of the default's margin (``VISUAL_FACES_SHARE``)."""
        n = int(hints.get("visual_faces", DEFAULT_VISUAL_FACES))
        return int(n * VISUAL_FACES_SHARE) if n > 0 else 0

    def generate_from_occupancy(
        self,
        image: np.ndarray,
        occupancy: np.ndarray,
        hints: dict[str, Any] | None = None,
    ) -> ArticulatedObject:
        """Teacher forcing: stage 2 on given part voxels (K, R, R, R) (slot 0 = base)."""
        obj = self.assemble(self.run(image, None, occupancy), hints)
        return fit_box_layout(obj) if self.box_layout else obj


def given_motions(hints: dict[str, Any]) -> dict[int, str]:
    """Slot -> motion of the parts whose motion the hints give (``hints["parts"]``, keyed by
    mask id = slot + 1: docs/input-format.md)."""
    out = {}
    for key, entry in (hints.get("parts") or {}).items():
        if isinstance(entry, dict) and entry.get("motion"):
            out[int(key) - 1] = str(entry["motion"])
    return out


def with_visuals(
    laid: ArticulatedObject, raw: ArticulatedObject, clean: ArticulatedObject
) -> ArticulatedObject:
    """``laid`` (the box layout of ``raw``) with ``clean``'s part meshes as the visuals:
    a movable part's mesh is its clean mesh, cut where it reaches toward a neighbour
    (``clip_from_neighbours``), a drawer drawn as little more than its front given the
    body of its collision box (``drawer_body``), plus the bar the layout added (the faces
    after ``raw``'s mesh), the base's the clean base plus the clean meshes of the parts the layout
    merged into it. A part ``clean`` lacks keeps its mesh. Visuals of two parts that
    would sweep into each other are cut apart (``sweep_clearance.keep_sweeps_apart``).
    Last, a movable part's visual is made its panel and its handle, nothing else
    (``mesh_repair.cleaning.panel_and_handle``: a drawer's front and tray joined, the bar
    as the handle, slivers of the cuts dropped), and the base loses its slivers."""
    names = {p.name for p in laid.parts}
    boxes = {p.name: _primitive_box(p) for p in laid.parts[1:] if p.primitives}
    meshes: dict[str, trimesh.Trimesh] = {}
    visuals: dict[str, trimesh.Trimesh] = {}  # movable parts' clean meshes (may be cut)
    bars: dict[str, trimesh.Trimesh] = {}  # the layout's bar handles (not cut)
    for p in laid.parts:
        c, r = _part(clean, p.name), _part(raw, p.name)
        meshes[p.name] = p.mesh
        if c is not None and r is not None and p is laid.parts[0]:
            merged = [q for q in raw.parts[1:] if q.name not in names]
            extra = [q.mesh for q in (_part(clean, m.name) for m in merged) if q is not None]
            meshes[p.name] = trimesh.util.concatenate([c.mesh, *extra]) if extra else c.mesh
        elif c is not None and r is not None:
            mesh = c.mesh
            if p.name in boxes:
                others = [b for name, b in boxes.items() if name != p.name]
                mesh = clip_from_neighbours(c.mesh, boxes[p.name], others)
            if p.joint is not None and p.joint.type == "prismatic" and p.primitives:
                body = drawer_body(mesh, _primitive_box(p), np.asarray(p.joint.axis, float))
                if body is not None:  # front and tray as one solid where both are closed
                    mesh = union_solids([mesh, body]) or trimesh.util.concatenate([mesh, body])
            visuals[p.name] = mesh
            n = len(r.mesh.faces)
            if len(p.mesh.faces) > n:  # the layout's bar handle
                bars[p.name] = p.mesh.submesh([np.arange(n, len(p.mesh.faces))], append=True)
    joints = {p.name: p.joint for p in laid.parts}
    visuals = keep_sweeps_apart(visuals, {k: b.bounds for k, b in bars.items()}, joints)
    parts = []
    for p in laid.parts:
        mesh = visuals.get(p.name, meshes[p.name])
        if p.name in visuals:  # a movable part: its panel (front and tray) and its handle
            mesh = panel_and_handle(mesh, bars.get(p.name))
        else:
            mesh = drop_slivers(mesh)
        parts.append(Part(p.name, p.semantic, mesh, p.joint, p.primitives, p.handle, p.material))
    out = ArticulatedObject(parts, laid.category, laid.scale, dict(laid.provenance))
    _floor_base_boxes(out)
    return out


#: A drawer's visual reaching less than this share of its collision box's depth back
#: gets the rest of its body (:func:`drawer_body`).
DRAWER_BODY_SHARE = 0.75
#: Wall thickness of that body, in generator units (the unit cube's side: ~1/64).
DRAWER_WALL = 0.016


def drawer_body(mesh: trimesh.Trimesh, box: np.ndarray, axis: np.ndarray) -> trimesh.Trimesh | None:
    """The body behind a drawer's visual ``mesh`` that its collision box (2, 3) has and
    the mesh lacks: an open-top tray (floor, two side walls, back wall, ``DRAWER_WALL``
    thick) from the box's back up to the mesh's back, coloured as the mesh. The decoded
    mesh of a drawer is often its front alone (the stage-1 grid draws it one or two
    voxels deep, the box layout gives it a body at least ``DRAWER_BODY`` of the object
    deep to slide in): opened in a simulator it would be a floating panel in front of a box the
    gripper cannot see, and its box scores as a panel. None when the mesh already
    reaches ``DRAWER_BODY_SHARE`` of the box's depth, or the drawer slides along z."""
    n = int(np.argmax(np.abs(axis)))
    if n == 2:
        return None
    sign = 1.0 if axis[n] > 0 else -1.0
    lo, hi = np.asarray(box[0], float), np.asarray(box[1], float)
    depth = hi[n] - lo[n]
    vlo, vhi = mesh.bounds
    back = lo[n] if sign > 0 else hi[n]
    reach = (hi[n] - vlo[n]) if sign > 0 else (vhi[n] - lo[n])
    if depth <= 0 or reach >= DRAWER_BODY_SHARE * depth:
        return None
    t = min(DRAWER_WALL, 0.25 * float(np.min(np.delete(hi - lo, n))))
    front = (vlo[n] + t) if sign > 0 else (vhi[n] - t)  # overlapping the front by a wall
    lat = 1 - n  # the horizontal axis across the drawer (n is 0 or 1)

    def wall(along: tuple, across: tuple, up: tuple) -> trimesh.Trimesh:
        """A box spanning ``along`` the slide, ``across`` it and ``up`` (each (a, b))."""
        w_lo, w_hi = np.empty(3), np.empty(3)
        w_lo[[n, lat, 2]] = min(along), min(across), min(up)
        w_hi[[n, lat, 2]] = max(along), max(across), max(up)
        return solid_box(w_lo, w_hi).to_mesh()

    span, full, height = (back, front), (lo[lat], hi[lat]), (lo[2], hi[2])
    pieces = [
        wall(span, full, (lo[2], lo[2] + t)),  # floor
        wall(span, (lo[lat], lo[lat] + t), height),  # side walls
        wall(span, (hi[lat] - t, hi[lat]), height),
        wall((back, back + sign * t), full, height),  # back wall
    ]
    body = union_solids(pieces) or trimesh.util.concatenate(pieces)
    colours = getattr(mesh.visual, "vertex_colors", None)
    colour = (
        np.asarray(colours)[:, :4].mean(axis=0).astype(np.uint8)
        if colours is not None and len(colours)
        else np.array(DEFAULT_COLOR, np.uint8)
    )
    body.visual.vertex_colors = np.tile(colour, (len(body.vertices), 1))
    return body


def _primitive_box(part: Part) -> np.ndarray:
    """(2, 3) bounds of a part's primitives (its collision geometry)."""
    b = np.array([q.to_mesh().bounds for q in part.primitives])
    return np.array([b[:, 0].min(axis=0), b[:, 1].max(axis=0)])


def clip_from_neighbours(
    mesh: trimesh.Trimesh, box: np.ndarray, neighbours: list[np.ndarray]
) -> trimesh.Trimesh:
    """``mesh`` (a movable part's visual, whose collision box (2, 3) is ``box``) cut where
    it reaches toward a neighbouring movable part (collision boxes ``neighbours``) across
    the gap the box layout left between their collision boxes: at the
    middle of that gap (along the axis the two boxes are furthest apart). A clean part
    mesh reaches a voxel or so past the box the layout fitted to its bulk (two stacked
    drawers' meshes overlapped by up to a fifth of their boxes at rest on the real dev
    split); cut, neighbours' meshes stay apart, as their collision boxes do, and a side
    with no neighbour keeps its full extent. A closed mesh stays closed (the cuts are
    capped); a cut that would leave nothing keeps the mesh."""
    out = mesh
    for other in neighbours:
        gaps = np.maximum(other[0] - box[1], box[0] - other[1])  # (3,) > 0: apart along it
        i = int(np.argmax(gaps))
        if gaps[i] < 0:
            continue  # the boxes overlap (not a layout's output): nothing to cut at
        toward = 1.0 if other[0][i] >= box[1][i] else -1.0  # side the neighbour is on
        at = box[1][i] + gaps[i] / 2 if toward > 0 else box[0][i] - gaps[i] / 2
        lo, hi = out.bounds
        if (hi[i] <= at) if toward > 0 else (lo[i] >= at):
            continue  # the mesh stays on its side
        rest = [j for j in range(3) if j != i]
        if np.any(lo[rest] >= other[1][rest]) or np.any(hi[rest] <= other[0][rest]):
            continue  # beside the neighbour: their boxes cannot meet
        normal = np.zeros(3)
        normal[i] = -toward  # keep the part's side of the plane
        origin = np.zeros(3)
        origin[i] = at
        cut = slice_closed(out, normal, origin)
        if cut is None:
            return mesh
        out = cut  # the cut's and the cap's new vertices coloured as the nearest old one
    return out


#: A movable part's raw decoded mesh whose face (the two larger sides of its bulk box)
#: covers less than this share of its clean mesh's face is not used for the box layout.
RAW_FACE_SHARE = 0.5


def door_panel(mesh: trimesh.Trimesh, thickness: float) -> trimesh.Trimesh:
    """The front slab of a part's mesh, ``thickness`` deep along x, closed at its back and
    coloured as the mesh: the door a part drawn as deep as a drawer becomes
    (``articulation.DRAWER_MIN_ASPECT``). The mesh itself when the cut leaves nothing."""
    x0 = float(mesh.bounds[1, 0]) - thickness
    if x0 <= float(mesh.bounds[0, 0]):
        return mesh
    slab = slice_closed(mesh, np.array([1.0, 0.0, 0.0]), np.array([x0, 0.0, 0.0]))
    return mesh if slab is None else slab


def lid_panel(mesh: trimesh.Trimesh, thickness: float) -> trimesh.Trimesh:
    """The top slab of a part's mesh, ``thickness`` deep along z, closed at its bottom and
    coloured as the mesh: the lid a part drawn as a drawer or a lid becomes when its
    given motion is ``lid``. The mesh itself when the cut leaves nothing."""
    z0 = float(mesh.bounds[1, 2]) - thickness
    if z0 <= float(mesh.bounds[0, 2]):
        return mesh
    slab = slice_closed(mesh, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, z0]))
    return mesh if slab is None else slab


def _raw_face_lost(raw: trimesh.Trimesh | None, clean: trimesh.Trimesh | None) -> bool:
    """Whether a movable part's raw decoded mesh has lost most of the face its clean
    mesh (the one its stage-1 occupancy shapes) keeps: the SDF of a part one or two
    voxels deep (a drawer front the mask relabelled) often decodes to a sliver of it,
    which the box layout would merge into the base."""
    if clean is None or len(clean.faces) == 0:
        return False
    if raw is None or len(raw.faces) == 0:
        return True

    def face(mesh: trimesh.Trimesh) -> float:
        ext = np.sort(np.diff(robust_bounds(mesh), axis=0)[0])
        return float(ext[1] * ext[2])

    return face(raw) < RAW_FACE_SHARE * face(clean)


def _floor_base_boxes(obj: ArticulatedObject) -> None:
    """Lower the base's bottom boxes (in place) to the lowest point of the visuals: the
    build stands an object on its meshes' lowest point, which must be where it collides
    (a clean mesh can reach below the raw meshes' layout; the base would drop onto the
    floor)."""
    base = obj.parts[0]
    boxes = [q for q in base.primitives if q.kind == "box"]
    if not boxes:
        return
    bottoms = [float(q.transform[2, 3] - q.size[2] / 2) for q in boxes]
    low, floor = min(bottoms), float(obj.bounds()[0][2])
    if floor >= low - 1e-9:
        return
    for q, b in zip(boxes, bottoms, strict=True):
        if b <= low + 1e-6:
            drop = b - floor
            q.size = np.array(q.size, dtype=float) + [0.0, 0.0, drop]
            q.transform = np.array(q.transform, dtype=float)
            q.transform[2, 3] -= drop / 2


def _part(obj: ArticulatedObject, name: str) -> Part | None:
    return next((p for p in obj.parts if p.name == name), None)
