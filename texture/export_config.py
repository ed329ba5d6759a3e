"""The options of one export, validated once at the boundary and saved in ``atlas.json``
(key ``config``), so ``mna export RUN --config atlas.json`` repeats an export exactly."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from mnacore import configs
from mnacore.errors import InputError

from .atlas_config import AtlasConfig
from .relax import RelaxConfig
from .textures import check_size

TEXTURES = ("checker", "uvgrid", "bake")


@dataclass
class ExportConfig:
    """Everything :func:`texture.pipeline.export_run` decides from."""

    texture: str = "checker"
    """checker, uvgrid, or bake (the input mesh's colours)."""
    size: int = 2048
    """Texture side in texels; the islands are packed for it."""
    padding: int = 8
    """Gutter around each island, texels."""
    square_size: float | None = None
    """Checker square in the unit-ball frame (None: the default, grown when too fine to draw)."""
    atlas: AtlasConfig = field(default_factory=AtlasConfig)

    @classmethod
    def from_options(cls, texture: str = "checker", size: int | str = 2048, padding: int = 8,
                     square_size: float | None = None, max_islands: int = AtlasConfig.max_islands,
                     relax: int = RelaxConfig.iterations) -> "ExportConfig":
        """The config of ``mna export``'s options (the rest at their defaults), validated."""
        cfg = cls(texture=texture, size=size, padding=padding, square_size=square_size)
        for value, name in ((max_islands, "--max-islands"), (relax, "--relax")):
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InputError(f"{name} must be a non-negative integer, got {value!r}")
        cfg.atlas.max_islands, cfg.atlas.relax.iterations = max_islands, relax
        return cfg.validate()

    def validate(self) -> "ExportConfig":
        if self.texture not in TEXTURES:
            raise InputError(f"unknown texture {self.texture!r}; choose from {', '.join(TEXTURES)}")
        self.size = check_size(self.size)
        p = self.padding
        if isinstance(p, bool) or not isinstance(p, int) or p < 0:
            raise InputError(f"--padding must be a non-negative integer, got {p!r}")
        s = self.square_size
        if s is not None and (isinstance(s, bool) or not isinstance(s, (int, float)) or not math.isfinite(s)
                              or s <= 0):
            raise InputError(f"--square-size must be a positive number, got {s!r}")
        a = self.atlas
        for value, name in ((a.max_islands, "atlas.max_islands"), (a.relax.iterations, "atlas.relax.iterations")):
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InputError(f"{name} must be a non-negative integer, got {value!r}")
        # the atlas is packed for the texture it is drawn on: one size, one gutter
        a.resolution, a.padding = self.size, self.padding
        return self


def load_export_config(path: str | Path) -> ExportConfig:
    """An :class:`ExportConfig` from an ``atlas.json`` (its ``config``) or a JSON/YAML file of
    its keys; strict: unknown keys and wrong types are errors."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"--config: cannot read {path}: {exc.__class__.__name__}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        import yaml

        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError:
            raise InputError(f"--config: {path} is neither JSON nor YAML") from None
    if isinstance(data, dict) and isinstance(data.get("config"), dict) and "atlas" in data:
        data = data["config"]  # an atlas.json: its resolved export config
    return configs.from_dict(data, ExportConfig, "export config").validate()
