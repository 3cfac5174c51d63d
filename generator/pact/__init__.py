"""PAct: part-decomposed articulated object generation (see docs/pact.md and the paper).

Modules: ``ss_vae`` (occupancy <-> latent), ``image_encoder`` (ViT / DINOv2 ViT-L/14),
``part_flow`` (part-aware flow transformer), ``flow`` (rectified flow loss and sampler),
``checkpoint`` (safetensors + JSON), ``stage1`` (configs, build, generate), ``model_configs``,
``preprocess`` (foreground crop before the encoder), ``foreground`` (silhouette U-Net).
"""

from . import (  # noqa: F401  (register the models)
    articulation,
    foreground,
    image_encoder,
    part_flow,
    slat_vae,
    ss_vae,
    stage2_flow,
)
from .checkpoint import load_checkpoint, save_checkpoint
from .flow import FlowTrainConfig, SamplerConfig, flow_loss, sample
from .model_configs import build
from .ss_vae import vae_loss
from .stage1 import Stage1Config, build_stage1, generate_parts, load_config

__all__ = [
    "FlowTrainConfig",
    "SamplerConfig",
    "Stage1Config",
    "build",
    "build_stage1",
    "flow_loss",
    "generate_parts",
    "load_checkpoint",
    "load_config",
    "sample",
    "save_checkpoint",
    "vae_loss",
]
