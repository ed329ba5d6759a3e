"""Neural-chart UVs on the user's own mesh: ``unwrap_mesh(vertices, faces, charts)``.

The fitted charts supply the *segmentation*; classical geometry processing supplies the
flattening (the charts' own UVs are not a usable start: input vertices off a chart's
domain project onto its border and fold). Stages (timed in ``stats["timings"]``):

1. ``prepare``: weld, turn faces wound against their neighbours, cut non-manifold edges,
   split non-manifold vertices, set degenerate faces aside (:mod:`texture.meshprep`); the
   input's faces and their order are kept.
2. ``assign``: chart per face by depth-preferring nearest-chart votes (:mod:`texture.assign`).
   A connected component none of whose faces comes within ``FAR_TOL`` of a chart is a
   *fallback* component: it becomes its own region, flattened the same classical way
   (cut to a disk, embedded, SLIM), and ``fallback_area_fraction`` reports its share.
3. ``clean``: one-face teeth smoothed away, chart borders moved within the charts' overlap
   to where they are shortest (:mod:`texture.borders`), small regions merged into their
   longest-border neighbour (:mod:`texture.regions`).
4. ``flatten``: each region split at pinches and cut to a disk, embedded by its conformal
   map or Tutte's (:func:`texture.flatten.start_map`), scaled so its UV area equals its 3D
   area (unit-ball frame); a disk with holes that flattens within ``slit_target`` uncut
   stays one island with its holes (``holed_islands``).
   A region that cannot be cut to a disk is split in two across its longest axis.
5. ``relax``: SLIM toward an isometry (:func:`texture.relax.relax_meshes`), all islands
   at the one scale above (so one texel density), border crossings prevented; each
   island's flips and boundary crossings are counted afterwards.
   ``merge``: neighbouring islands whose union flattens within ``slit_target`` with
   shorter seams are joined (:mod:`texture.merge`).
6. ``split``: islands above ``target_distortion`` halved and re-flattened; islands too long
   to pack densely halved across their length, UVs kept (:mod:`texture.unwrap_islands`);
   then faces hanging on their island by one edge move across the seam (:mod:`texture.ears`).
7. ``pack``: the islands turned as packs best and, below ``pack_target``, halved by the
   cuts that buy it for the least seam (:func:`texture.unwrap_layout.choose_layout`), then :func:`texture.pack.pack_islands` at
   ``resolution`` and ``padding`` (the search compares real packings).

Output (:class:`Unwrap`): a :class:`UVMesh` whose face ``i`` is input face ``i`` with
the same corner order, in the input frame (except a face wound against its neighbours,
``prepare``'s ``turned_faces``: it is written wound like them, corners 2 and 3 swapped, so
that its texture does not read mirrored where its neighbours' reads right); output vertex = one per distinct (input
vertex, island vertex) pair, so input vertices are duplicated only along seams (and where
the input was non-manifold). A degenerate face (zero area or a repeated index) gets three
vertices of its own (its corners' 3D positions) on one UV point of a neighbouring island:
a zero-area UV triangle inside that island. A face that repeats an earlier one
(``prepare``'s ``copied_faces``) gets that face's UV triangle.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Callable

import numpy as np

from mnacore.charts import ChartGrids
from mnacore.triangles import signed_areas, triangle_areas
from mnacore.uvmesh import UVMesh, weld_ids

from .assign import FAR_TOL, NEAR_TOL, assign_faces, chart_surfaces
from .borders import shortest_borders
from .ears import move_ears
from .halving import refine_islands
from .long_islands import split_long_islands
from .merge import merge_islands
from .meshprep import prepare_mesh
from .regions import MIN_FRACTION, clean_labels, face_adjacency, regions, smooth_borders
from .relax import MULTIRES_FACES, SLIM_MAX_FACES
from .unwrap_islands import (
    WHOLE,
    Island,
    audit_islands,
    flatten_region,
    holed_rule,
    prefer_whole,
    relax_islands,
    slit_islands,
    whole_components,
)
from .unwrap_layout import FIRST_SEAM_GAIN, MAX_CUTS, choose_layout


@dataclass
class UnwrapConfig:
    """Options of :func:`unwrap_mesh` (``mna unwrap``)."""

    min_fraction: float = MIN_FRACTION
    """Regions below this fraction of their component's area merge into a neighbour."""
    smooth_passes: int = 20
    """Most border-smoothing sweeps before merging (:func:`texture.regions.smooth_borders`; 0 = off)."""
    shortest_borders: bool = True
    """Move chart borders, within the charts' overlap, to where they are shortest
    (:func:`texture.borders.shortest_borders`)."""
    near_tol: float = NEAR_TOL
    """Charts within this of the nearest (unit-ball frame) compete on domain depth."""
    far_tol: float = FAR_TOL
    """Samples farther than this from every chart are not reached by the fit."""
    slim_iterations: int = 200
    """Most SLIM iterations per island."""
    slim_min_gain: float = 1e-4
    """Stop an island's SLIM once an iteration gains less than this in mean energy excess."""
    scaffold: bool = True
    """Where an island's free SLIM overlaps itself and the border-guarded run of
    :mod:`texture.relax` would restart from the start map, or stalls above ``slit_target``,
    SLIM with a scaffold (:mod:`texture.scaffold`) finds the best map that does not overlap
    (:func:`texture.flatten.relax_disk`; merge trials keep the guarded run: see
    :mod:`texture.merge`)."""
    multires_faces: int = MULTIRES_FACES
    """Islands above this many faces are flattened by :mod:`texture.multires` (SLIM on a
    coarse copy, then ARAP): SLIM's iteration costs 0.26 s at 46k faces and 17-23 s at 418k,
    a coarse SLIM plus ARAP about 1 s at 47k. Below it SLIM alone is fast enough."""
    slim_max_faces: int = SLIM_MAX_FACES
    """An island above this many faces whose two-resolution flattening fails is not handed to
    SLIM (minutes at 400k faces) but kept at its start, so the split stage halves it."""
    resolution: int = 2048
    """Texture size the islands are packed for (texels)."""
    padding: int = 8
    """Gutter around each island (texels)."""
    max_split_depth: int = 6
    """A region that cannot be cut to a disk is halved at most this many times."""
    slit_target: float = 0.1
    """Islands whose energy excess (mean ``tr g + tr g^-1 - 4``) stays above this after SLIM
    get slits (:mod:`texture.slits`)."""
    max_slits: int = 8
    """Most slits per island."""
    merge_max_faces: int = 20_000
    """Neighbouring islands whose union flattens within ``slit_target`` with shorter seams
    are merged (:mod:`texture.merge`; 0 = off); unions above this many faces get a cheaper
    trial, and only where it can pass (a disk of low total curvature), for time only: a trial
    flattens, relaxes and slits the union, 2-10 s at 5-12k faces, 55 s for a 58k-face union of
    the 111k-face bunny."""
    whole_max_faces: int = 5_000
    """Components the charts split into several regions are first tried whole (one island)
    when they have at most this many faces (:func:`_whole_components`)."""
    target_distortion: float = 0.14
    """While the islands' distortion_metric (the harness's formula) exceeds this after slits,
    the island contributing most is halved and re-flattened (issue target: 0.15)."""
    max_split_rounds: int = 16
    """Most halvings for ``target_distortion``."""
    long_fill: float = 0.6
    """Islands longer than the side of a square holding all islands at this utilisation are
    cut across their length (:func:`texture.long_islands.split_long_islands`)."""
    long_max_splits: int = 4
    """Most islands cut so, each into as many pieces as its length asks (0 = off)."""
    long_max_islands: int = 8
    """No such halving (nor an ordinary packing halving) takes a connected component from within
    this many islands past it (a part already past it is halved on gain alone, one at it only
    by the packing search for ``pack_first_seam_gain``: :func:`texture.halving.may_halve`)."""
    pack_target: float = 0.6
    """Islands are halved for packing (:mod:`texture.unwrap_layout`) only while no layout packs
    this utilisation (coarse)."""
    pack_cut_gain: float = 0.02
    """A packing halving adds seam: kept only when it gains this much utilisation (coarse)."""
    pack_first_seam_gain: float = FIRST_SEAM_GAIN
    """A packing halving of a part that flattened as one island (its first seam), or of a part
    at ``long_max_islands`` (past the island target), is kept only for this much utilisation:
    five times ``pack_cut_gain`` (an unrolled cylinder's strip gains 0.25 from it,
    inspired_mesh's open patch 0.22: both are cut; its length split had gained 0.03)."""
    pack_max_cuts: int = MAX_CUTS
    """Most packing halvings (0 = only the islands' turns are searched). Each must gain
    ``pack_cut_gain`` and the rounds stop at the target or the first halving that does not pay,
    so the cap only bounds a run of halvings that all pay: a part flattened whole (the eight's
    genus-2 surface) took three (0.30 -> 0.49 -> 0.59 -> 0.63) where the cap of 2 left 0.59."""
    holed_islands: bool = True
    """A region that is a disk with holes stays uncut where its conformal map embeds within
    ``slit_target`` (:func:`texture.flatten.holed_map`): no cuts from its holes to its border."""
    move_ears: bool = True
    """Faces hanging on their island by one edge move across the seam (:mod:`texture.ears`)."""


@dataclass
class Unwrap:
    """Result of :func:`unwrap_mesh`: the UV mesh (input frame), island per face, stats."""

    mesh: UVMesh
    island: np.ndarray
    stats: dict = field(default_factory=dict)


def _output_mesh(prep, islands: list[Island], packed_uv: np.ndarray,
                 offsets: np.ndarray) -> tuple[UVMesh, np.ndarray, dict]:
    """Assemble the input-ordered UV mesh from the packed islands (see module docstring)."""
    F = len(prep.faces)
    corner_node = np.full((F, 3), -1, np.int64)  # global island-vertex id per input corner
    face_island = np.full(F, -1, np.int64)
    node_work = np.concatenate([isl.work_vertex for isl in islands])
    for i, isl in enumerate(islands):
        in_faces = prep.input_face[isl.work_faces]
        corner_node[in_faces] = isl.faces + offsets[i]
        face_island[in_faces] = i
    # degenerate faces: their corners' UVs in one island touching them
    weld_of_work = np.full(len(prep.work_vertices), -1, np.int64)
    weld = weld_ids(prep.vertices)
    weld_of_work[prep.corner_vertex[prep.work_face >= 0].ravel()] = weld[prep.faces[prep.work_face >= 0].ravel()]
    node_weld = weld_of_work[node_work]
    node_island = np.repeat(np.arange(len(islands)), [len(isl.uv) for isl in islands])
    # first island vertex (lowest id) on each welded point, -1 where none
    first_node = np.full(len(prep.vertices), -1, np.int64)
    welds, first_at = np.unique(node_weld, return_index=True)
    first_node[welds[welds >= 0]] = first_at[welds >= 0]
    isolated = 0
    degenerate = np.flatnonzero((prep.work_face < 0) & (prep.copy_of < 0))
    for f in degenerate:
        nodes = first_node[weld[prep.faces[f]]]
        first = next((int(n) for n in nodes if n >= 0), None)
        if first is None:
            isolated += 1
            corner_node[f] = 0  # nowhere to sit: collapsed onto one UV point
            face_island[f] = 0
            continue
        # all three corners on one UV point (own copies): zero UV area, so the face is
        # skipped by the distortion measures instead of carrying a near-zero, signed UV area
        corner_node[f] = first
        face_island[f] = int(node_island[first])
    # output vertex per (input vertex, node); a face repeating a vertex gets distinct copies
    # a face wound against its neighbours is written wound like them (the working face's
    # corner order: corners 1 and 2 swapped), so no island holds both windings
    fr = prep.faces.copy()
    turned = prep.input_face[prep.turned]
    copies = np.flatnonzero(prep.copy_of >= 0)
    orig = prep.copy_of[copies]
    turned = np.r_[turned, copies[np.isin(orig, turned)]]  # a copy is wound as its original is written
    fr[turned] = fr[turned][:, [0, 2, 1]]
    # a copy's corners take its original's nodes (the corner on the same welded point): the
    # same UV triangle, in the same island
    same = weld[fr[copies]][:, :, None] == weld[fr[orig]][:, None, :]
    corner_node[copies] = np.take_along_axis(corner_node[orig], same.argmax(2), 1)
    face_island[copies] = face_island[orig]
    corner_key = np.stack([fr.ravel(), corner_node.ravel()], 1)
    rep = np.zeros((F, 3), np.int64)
    rep[:, 1] = fr[:, 1] == fr[:, 0]
    rep[:, 2] = (fr[:, 2] == fr[:, 0]) | (fr[:, 2] == fr[:, 1])
    rep[:, 2] += (fr[:, 2] == fr[:, 0]) & (fr[:, 2] == fr[:, 1])
    rep[degenerate] = [3, 4, 5]
    corner_key = np.column_stack([corner_key, rep.ravel()])
    uniq, inv = np.unique(corner_key, axis=0, return_inverse=True)
    mesh = UVMesh(prep.vertices[uniq[:, 0]], inv.reshape(F, 3).astype(np.int64), packed_uv[uniq[:, 1]])
    return mesh, face_island, {"isolated_degenerate_faces": isolated}


def _assigned_labels(xyz, prep, charts: ChartGrids, cfg: UnwrapConfig):
    """(face labels: a chart, or ``n_charts + component`` for a component no chart reaches;
    the assignment; per component whether a chart reached it)."""
    asg = assign_faces(xyz, prep.work_faces, chart_surfaces(charts), cfg.near_tol, cfg.far_tol)
    comp = prep.component
    reached = np.bincount(comp, weights=(~asg.far).astype(float), minlength=prep.n_components) > 0
    return np.where(~reached[comp], charts.n_charts + comp, asg.label), asg, reached


def _flattened(xyz, prep, label, reg, cfg: UnwrapConfig, stage) -> tuple[list, dict]:
    """(islands of the whole components and of every other region, flatten stats)."""
    stage("whole")
    comp = prep.component
    fstats = {"region_splits": 0, "cut_edges": 0, "holed": 0}
    islands, whole = whole_components(xyz, prep.work_faces, comp, reg, cfg, fstats)
    fstats["whole_components"] = len(whole)
    stage("flatten")
    order = np.argsort(reg, kind="stable")
    bounds = np.searchsorted(reg[order], np.arange(int(reg.max()) + 2))
    holed = holed_rule(cfg)
    for r in range(int(reg.max()) + 1):
        sel = order[bounds[r]:bounds[r + 1]]
        if comp[sel[0]] in whole:
            continue
        islands += flatten_region(xyz, prep.work_faces[sel], sel, int(label[sel[0]]), cfg.max_split_depth, fstats,
                                  holed)
    return islands, fstats


def _packed(islands: list, comp: np.ndarray, cfg: UnwrapConfig, note: Callable[[str], None] | None = None):
    """(packing, islands as packed, vertex offset of each island, islands reflected, layout
    search stats): every island counter-clockwise like the input's winding (no island mirrored
    as seen from outside; one whose faces all turned clockwise is reflected in u), then turned
    and halved (:func:`texture.unwrap_layout.choose_layout`: rotations and cuts along edges
    only, never a mirror), then packed."""
    mirrored = 0
    for isl in islands:
        if signed_areas(isl.uv, isl.faces).sum() < 0:
            isl.uv = isl.uv * np.array([-1.0, 1.0])
            mirrored += 1
    choice = choose_layout(islands, comp, cfg, note)
    offsets = np.cumsum([0] + [len(isl.uv) for isl in choice.islands])
    return choice.packing, choice.islands, offsets, mirrored, choice.stats  # the packer never mirrors an island (texture.pack)


def _pack_stats(packing) -> dict:
    return {"utilization": packing.utilization, "packer": packing.packer, "scale": packing.scale,
            "texels_per_unit": packing.texels_per_unit, "resolution": packing.resolution,
            "padding": packing.padding}


#: the stages of :func:`unwrap_mesh`, in order (``stats["timings"]`` keys; ``progress`` names)
STAGES = ("prepare", "assign", "clean", "whole", "flatten", "relax", "slits", "merge", "split", "pack")


class _Stages:
    """Times the stages (one ends where the next starts) and tells ``progress`` each start."""

    def __init__(self, progress: Callable[[str], None] | None):
        self.timings: dict[str, float] = {}
        self.progress, self.name, self.t0 = progress, None, 0.0

    def __call__(self, name: str | None) -> None:
        now = time.perf_counter()
        if self.name is not None:
            self.timings[self.name] = now - self.t0
        self.name, self.t0 = name, now
        if name is not None and self.progress is not None:
            self.progress(name)


def unwrap_mesh(vertices, faces, charts: ChartGrids, cfg: UnwrapConfig | None = None,
                progress: Callable[[str], None] | None = None) -> Unwrap:
    """UV-map ``(vertices (V,3), faces (F,3))`` (input frame) with ``charts``; see module docstring.
    ``progress``: called with each stage's name (:data:`STAGES`) as it starts; where it has a
    ``note`` attribute, that is called with a stage's own progress (the merge's rounds, the
    packing search's steps)."""
    cfg = cfg or UnwrapConfig()
    stage = _Stages(progress)
    stage("prepare")
    prep = prepare_mesh(vertices, faces)
    xyz = charts.normalization.apply(prep.work_vertices)

    stage("assign")
    label, asg, reached = _assigned_labels(xyz, prep, charts, cfg)
    fallback = ~reached[prep.component]
    area = triangle_areas(xyz, prep.work_faces)

    stage("clean")
    adj = face_adjacency(xyz, prep.work_faces)
    label, smoothed = smooth_borders(label, adj, cfg.smooth_passes)
    border_stats = {}
    if cfg.shortest_borders:
        label, border_stats = shortest_borders(label, asg.reach, adj)
    label, clean_stats = clean_labels(label, area, prep.component, adj, cfg.min_fraction)
    clean_stats.update(smoothed_faces=smoothed, **border_stats)
    reg = regions(label, adj)

    islands, fstats = _flattened(xyz, prep, label, reg, cfg, stage)
    stage("relax")
    relax_stats = relax_islands([isl for isl in islands if isl.label != WHOLE], cfg)
    stage("slits")
    slit_stats = slit_islands([isl for isl in islands if isl.label != WHOLE], cfg)
    islands, swapped = prefer_whole(islands, fstats.pop("whole_trials", {}), prep.component)
    fstats["whole_preferred"] = swapped
    stage("merge")
    note = getattr(progress, "note", None)
    islands, merge_stats = merge_islands(islands, xyz, prep.work_faces, adj, cfg, note=note)
    stage("split")
    islands, split_stats = refine_islands(islands, xyz, prep.work_faces, cfg)
    islands, long_stats = split_long_islands(islands, prep.component, cfg)
    split_stats.update(long_stats)
    ear_stats = {}
    if cfg.move_ears:
        islands, ear_stats = move_ears(islands)

    islands, audit_stats = audit_islands(islands, xyz, prep.work_faces, cfg)
    split_stats.update(audit_stats)

    stage("pack")
    packing, islands, offsets, mirrored, layout_stats = _packed(islands, prep.component, cfg, note)
    stage(None)
    t = stage.timings
    mesh, face_island, out_stats = _output_mesh(prep, islands, packing.uv, offsets)
    total = float(area.sum())
    assignment = {**asg.stats, "far_area_fraction": float(area[asg.far].sum() / total),
                  "fallback_components": int((~reached).sum()), "fallback_faces": int(fallback.sum()),
                  "fallback_area_fraction": float(area[fallback].sum() / total)}
    stats = {"prepare": prep.stats, "assignment": assignment, "regions": clean_stats, "islands": len(islands),
             "flatten": fstats, "relax": relax_stats, "slits": slit_stats, "merge": merge_stats, "splits": split_stats, "ears": ear_stats,
             "pack": {**_pack_stats(packing), "layout": layout_stats}, **out_stats, "islands_reflected": mirrored, "config": asdict(cfg),
             "timings": t}
    return Unwrap(mesh, face_island, stats)
