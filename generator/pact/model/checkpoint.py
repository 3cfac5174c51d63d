"""Checkpoints: one folder per model, ``model.safetensors`` (weights) + ``config.json``.

``config.json`` = {"schema": "pact.checkpoint", "version": 1, "model": <model name>,
"config": <config dataclass as a dict>}. Folders are written under a temporary name and
renamed, so a half-written checkpoint never looks whole.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import torch
import torch.nn as nn
from safetensors.torch import load_file, save_file

from generator.pact.model import model_configs

SCHEMA = "pact.checkpoint"
VERSION = 1


class CheckpointError(ValueError):
    """A folder that is not a PAct checkpoint of a known schema/version."""


def save_checkpoint(model: nn.Module, path: str | Path, extra: dict | None = None) -> Path:
    """Write ``model`` (a registered model with a ``cfg`` dataclass) to folder ``path``."""
    path = Path(path)
    name = getattr(model, "model_name", None)
    if name is None:
        raise CheckpointError(f"{type(model).__name__} is not a registered model")
    meta = {
        "schema": SCHEMA,
        "version": VERSION,
        "model": name,
        "config": dataclasses.asdict(model.cfg),
        "extra": extra or {},
    }
    tmp = path.with_name(path.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    tensors = {k: v.detach().to("cpu").contiguous() for k, v in model.state_dict().items()}
    save_file(tensors, str(tmp / "model.safetensors"))
    (tmp / "config.json").write_text(json.dumps(meta, indent=2))
    if path.exists():
        shutil.rmtree(path)
    tmp.rename(path)
    return path


def read_checkpoint_meta(path: str | Path) -> dict:
    meta_path = Path(path) / "config.json"
    if not meta_path.is_file():
        raise CheckpointError(f"{path} has no config.json; is it a checkpoint folder?")
    meta = json.loads(meta_path.read_text())
    if meta.get("schema") != SCHEMA or meta.get("version") != VERSION:
        raise CheckpointError(
            f"{meta_path}: schema {meta.get('schema')!r} v{meta.get('version')}, "
            f"expected {SCHEMA!r} v{VERSION}"
        )
    return meta


def load_checkpoint(path: str | Path, device: torch.device | str = "cpu") -> nn.Module:
    """Rebuild the model from ``config.json`` and load its weights (strict)."""
    path = Path(path)
    meta = read_checkpoint_meta(path)
    cfg = dict(meta["config"])
    if cfg.get("weights"):
        cfg["weights"] = None  # pretrained weights are already in the checkpoint
    model = model_configs.build(meta["model"], cfg)
    state = load_file(str(path / "model.safetensors"), device=str(device))
    model.load_state_dict(state, strict=True)
    return model.to(device)


#: The weights shipped with the package; training writes here only when told to.
SHIPPED_WEIGHTS = Path(__file__).parents[1] / "weights"


def check_output_dir(out: str | Path, write_shipped: bool = False) -> None:
    """Raise ValueError when ``out`` lies inside :data:`SHIPPED_WEIGHTS` and
    ``write_shipped`` is False (a training run must not overwrite the shipped weights
    by accident)."""
    target, shipped = Path(out).resolve(), SHIPPED_WEIGHTS.resolve()
    if (target == shipped or shipped in target.parents) and not write_shipped:
        raise ValueError(
            f"{out}: is inside the shipped weights ({SHIPPED_WEIGHTS}); training writes there "
            "only when told to (--write-shipped-weights)"
        )
