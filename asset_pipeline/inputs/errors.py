"""The one error of the input folder format: an item is unusable."""

from __future__ import annotations


class InputError(ValueError):
    """An input item is unusable; the message names the file and what is wrong."""
