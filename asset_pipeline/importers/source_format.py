"""What the import formats share: the error for a malformed source, the source category
names mapped to ours, and asset ids made from source names.
"""

from __future__ import annotations

import logging
import re

log = logging.getLogger(__name__)


#: Source categories (PartNet-Mobility / CAGE / SINGAPO / PAct class ids) -> ours.
CATEGORY_MAP = {
    "storagefurniture": "cabinet",
    "cabinet": "cabinet",
    "table": "desk",
    "desk": "desk",
    "microwave": "microwave",
    "oven": "oven",
    "dishwasher": "dishwasher",
    "refrigerator": "refrigerator",
    "fridge": "refrigerator",
    "washingmachine": "washing_machine",
    "washing_machine": "washing_machine",
}


class ImportFormatError(ValueError):
    """An import source is unsupported or malformed; the message names the file and field."""


def sanitize_id(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._-")
    return s or "object"
