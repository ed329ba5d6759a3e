"""Options of the export's atlas stages (:func:`texture.atlas.build_atlas`)."""
from __future__ import annotations

from dataclasses import dataclass, field

from .relax import RelaxConfig
from .trim import TrimConfig


@dataclass
class AtlasConfig:
    """Options of :func:`texture.atlas.build_atlas`."""

    resolution: int = 2048
    """Texture size (texels) the islands are packed for."""
    padding: int = 8
    """Gutter around each island, in texels at ``resolution``."""
    trim: TrimConfig = field(default_factory=TrimConfig)
    orient: bool = True
    """With a reference surface, reorient inside-out parts of charts (:mod:`texture.orient`)."""
    orient_fragment_island: float = 2e-4
    """An inside-out fragment (under ``trim.min_island_fraction``) that the orientation's
    drop budget cannot take becomes an island of its own, reoriented, when it is at least
    this fraction of the total area; smaller ones stay with their surroundings (0 = all do)."""
    relax: RelaxConfig = field(default_factory=RelaxConfig)
    """Re-flatten every island toward an isometry before packing (:mod:`texture.relax`;
    ``relax.iterations = 0`` keeps the charts' own UVs)."""
    max_islands: int = 6
    """Cut the largest island in two when that packs tighter, if the atlas then has at most
    this many islands (0 = never cut)."""
    split_gain: float = 0.02
    """Cut only when utilisation (coarse packing) rises by at least this much: a cut adds a seam."""
    target_utilization: float = 0.6
    """When neither the uncut islands nor a centroid cut packs this tight (coarse packing),
    off-centre cuts are packed too: about 8 more coarse searches (a few seconds). And when
    the relaxed islands' best layout stays below it, the charts' own UVs are laid out too
    and kept instead if they reach it (``relax_kept``). 0 = never."""
    seed: int = 0
    """Seed of the surface samples used for the coverage check."""
