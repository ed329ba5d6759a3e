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
    """The island target of the packing search (:func:`texture.atlas_stages.layout_goal`):
    islands are halved along short cuts on the surface while that packs tighter, never from
    within this many to past it, one at it only for a first seam's gain (the unwrap's
    ``pack_first_seam_gain``); an atlas already past it is halved on gain alone. It also
    bounds the orientation's fragment islands. 0 = never cut."""
    split_gain: float = 0.02
    """A halving is kept only where utilisation rises by at least this much: it adds a seam
    (the unwrap's ``pack_cut_gain``)."""
    target_utilization: float = 0.6
    """Islands are halved only while the layout packs below this (the unwrap's
    ``pack_target``; 0 = never)."""
    seed: int = 0
    """Seed of the surface samples used for the coverage check."""
