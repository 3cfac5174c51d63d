"""The photo parser: a bare photo of a cabinet, desk or appliance -> its category, a part
mask (base and movable parts) and each movable part's motion (``generator.motions``).

    from generator.parser import PhotoParser
    parsed = PhotoParser.default().parse(image)

Network: ``model.py``; training data and augmentation: ``data.py``; training:
``train.py``; inference: ``inference.py``; model card: ``docs/parser.md``.
"""

from generator.parser.inference import (
    BoxGrouping,
    ParsedPart,
    ParsedPhoto,
    PhotoParser,
    PixelMaps,
    RegionScores,
    instances,
    weights_dir,
)
from generator.parser.model import CATEGORIES, SEG_CLASSES, ParserConfig, ParserNet

__all__ = [
    "CATEGORIES",
    "BoxGrouping",
    "SEG_CLASSES",
    "ParsedPart",
    "ParsedPhoto",
    "ParserConfig",
    "ParserNet",
    "PhotoParser",
    "PixelMaps",
    "RegionScores",
    "instances",
    "weights_dir",
]
