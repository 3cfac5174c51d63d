"""PAct: part-decomposed articulated object generation (see docs/pact.md and the paper).

Three subpackages: ``model`` (the networks: ``ss_vae`` occupancy <-> latent, ``image_encoder``,
``part_flow`` the part-aware flow transformer, ``flow`` rectified flow, ``stage1`` and ``stage2``
as wholes, ``articulation`` the head, ``checkpoint``, ``model_configs``, ``preprocess``,
``foreground``), ``training`` (data pipelines and the training entry points) and ``inference``
(``generate.PActGenerator`` and what turns samples into articulated objects).
"""

from generator.pact.model import (  # noqa: F401  (register the models)
    articulation,
    foreground,
    image_encoder,
    part_flow,
    slat_vae,
    ss_vae,
    stage2_flow,
)
from generator.pact.model.checkpoint import load_checkpoint, save_checkpoint
from generator.pact.model.flow import FlowTrainConfig, SamplerConfig, flow_loss, sample
from generator.pact.model.model_configs import build
from generator.pact.model.ss_vae import vae_loss
from generator.pact.model.stage1 import Stage1Config, build_stage1, generate_parts, load_config

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
