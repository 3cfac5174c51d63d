"""Training data for PAct: procedural objects rendered with SAPIEN into npz shards.

``build_dataset`` writes a dataset folder (docs/dataset.md); ``Dataset`` / ``load_shard``
read it back without torch. ``unpack_occupancy`` turns the packed occupancy bits into
(S, R, R, R) bool grids. ``write_parser_data`` writes the photo parser's training data
(docs/dataset.md, "Parser training data").
"""

from generator.data.build import build_dataset
from generator.data.parser_data import ParserDataError, write_parser_data
from generator.data.shards import (
    JOINT_TYPES,
    SEMANTICS,
    Dataset,
    DatasetError,
    load_shard,
    pack_occupancy,
    unpack_occupancy,
)

__all__ = [
    "JOINT_TYPES",
    "SEMANTICS",
    "Dataset",
    "DatasetError",
    "ParserDataError",
    "build_dataset",
    "load_shard",
    "pack_occupancy",
    "unpack_occupancy",
    "write_parser_data",
]
