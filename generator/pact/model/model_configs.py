"""Model names -> (module class, config dataclass), and configs read from JSON.

Models register themselves with ``@register("name", ConfigCls)`` in their own file;
``build("part_flow", cfg)`` makes one from a config dataclass or a plain dict (as read
from JSON), so the small and full models are the same code with different data.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch.nn as nn

_MODELS: dict[str, tuple[type[nn.Module], type]] = {}


class UnknownModelError(KeyError):
    """Raised for a name nobody registered; the message lists the known names."""


def register(name: str, config_cls: type) -> Callable[[type[nn.Module]], type[nn.Module]]:
    def deco(cls: type[nn.Module]) -> type[nn.Module]:
        if name in _MODELS and _MODELS[name][0] is not cls:
            raise ValueError(f"model name {name!r} registered twice")
        _MODELS[name] = (cls, config_cls)
        cls.model_name = name  # type: ignore[attr-defined]
        return cls

    return deco


def names() -> list[str]:
    return sorted(_MODELS)


def config_class(name: str) -> type:
    return _lookup(name)[1]


def make_config(name: str, cfg: Any = None) -> Any:
    """A config dataclass for ``name`` from a dataclass, a dict (JSON) or None (defaults)."""
    _, config_cls = _lookup(name)
    if cfg is None:
        return config_cls()
    if isinstance(cfg, config_cls):
        return cfg
    if isinstance(cfg, dict):
        return config_from_dict(config_cls, cfg)
    raise TypeError(f"config for {name!r} must be {config_cls.__name__} or dict, got {type(cfg)}")


def build(name: str, cfg: Any = None) -> nn.Module:
    """Instantiate the model registered as ``name`` (respects ``with torch.device(...)``)."""
    cls, _ = _lookup(name)
    return cls(make_config(name, cfg))


def config_from_dict(config_cls: type, data: dict[str, Any]) -> Any:
    """Dataclass from a dict; unknown keys are an error (a typo should not pass silently)."""
    fields = {f.name: f for f in dataclasses.fields(config_cls)}
    unknown = set(data) - set(fields)
    if unknown:
        raise ValueError(
            f"unknown {config_cls.__name__} keys {sorted(unknown)}; known: {sorted(fields)}"
        )
    kwargs = {k: (tuple(v) if isinstance(v, list) else v) for k, v in data.items()}
    return config_cls(**kwargs)


def sections_from_dict(classes: dict[str, type], data: dict[str, Any], what: str) -> dict[str, Any]:
    """A stage config's sections (name -> config dataclass) from its JSON dict: a
    missing section takes its defaults, an unknown one is an error naming ``what``."""
    unknown = set(data) - set(classes)
    if unknown:
        raise ValueError(f"unknown {what} config sections {sorted(unknown)}")
    return {k: config_from_dict(cls, data.get(k, {})) for k, cls in classes.items()}


def read_config_json(name_or_path: str | Path, config_dir: Path, what: str) -> dict[str, Any]:
    """``name`` (no suffix) -> ``config_dir/name.json``, else a JSON path; its contents."""
    path = Path(name_or_path)
    if not path.suffix:
        path = config_dir / f"{name_or_path}.json"
    if not path.is_file():
        known = sorted(p.stem for p in config_dir.glob("*.json"))
        raise FileNotFoundError(f"no {what} config {name_or_path!r} at {path}; packaged: {known}")
    return json.loads(path.read_text())


def _lookup(name: str) -> tuple[type[nn.Module], type]:
    if name not in _MODELS:
        raise UnknownModelError(f"no model registered as {name!r}; known: {names()}")
    return _MODELS[name]
