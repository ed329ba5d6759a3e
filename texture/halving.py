"""Halving islands: for distortion (the split stage), for length, and the cut itself.

Three callers cut an island in two: :func:`refine_islands` while the atlas is too distorted
(spectral bisection, re-flattened), :func:`split_long_islands` for islands too long to pack
densely, and the packing search (:mod:`texture.unwrap_layout`) for utilisation. The last two
keep the island's UVs (:func:`halve_across`); every cut runs along the input's edges and is
refused where it would zigzag (:data:`ZIGZAG`).
"""
from __future__ import annotations

import numpy as np

from mnacore.triangles import signed_areas, triangle_areas

from .ears import smooth_cut
from .relax import boundary_length, energy_excess
from .unwrap_islands import BLOWUP, SPLIT, Island, flatten_halves, holed_rule, relax_islands, slit_islands


def atlas_distortion(islands: list[Island]) -> float:
    """DESIGN's ``distortion_metric`` of all islands together (UV-area weighted, the harness's
    formula: ``2 sqrt(E[tr g] E[tr g^-1]) - 4``, scale-free)."""
    from mnacore import distortion as D

    from .distortion_faces import face_geometry

    jac, ws = [], []
    for isl in islands:
        geom = face_geometry(isl.xyz, isl.faces, isl.uv)
        jac.append(geom.jac[geom.valid])
        ws.append(np.abs(geom.uv_area[geom.valid]))
    return D.all_distortions(D.metric_tensor(np.concatenate(jac)), weights=np.concatenate(ws)).metric


def zigzag(isl: Island, pieces: list[Island]) -> bool:
    """Whether cutting ``isl`` into ``pieces`` added more seam than ``ZIGZAG`` times the
    island's 3D diameter (its bounding box's diagonal): a cut across a region runs no longer
    than the region is wide where the mesh has edges that way; where it has none (long thin
    faces) the cut zigzags along them (see ``ZIGZAG``)."""
    added = 0.5 * (sum(boundary_length(p.xyz, p.faces) for p in pieces) - boundary_length(isl.xyz, isl.faces))
    return added > ZIGZAG * float(np.linalg.norm(np.ptp(isl.xyz, axis=0)))


def refine_islands(islands: list[Island], xyz: np.ndarray, work_faces: np.ndarray,
                   cfg) -> tuple[list[Island], dict]:
    """While the islands' :func:`atlas_distortion` exceeds ``cfg.target_distortion``, halve the
    island that contributes most (its 3D area times its energy excess) and flatten, relax
    and slit the halves; at most ``cfg.max_split_rounds`` rounds. One island at a time keeps
    the count low where a single island carries the distortion; a halving whose halves
    contribute no less (3D area times excess) is rejected and that island left alone. (Rejecting
    by the atlas's distortion instead gets stuck: where the worst island is a long, curved
    region, its first halving can raise the atlas's distortion (1.94 -> 3.87 once) before
    later halvings bring it down (to 0.03).)"""
    st = {"islands_split": 0, "region_splits": 0, "cut_edges": 0}
    area = [float(triangle_areas(isl.xyz, isl.faces).sum()) for isl in islands]
    excess = [energy_excess(isl.xyz, isl.uv, isl.faces) for isl in islands]
    frozen = [False] * len(islands)  # halving it did not lower the atlas's distortion
    current = atlas_distortion(islands)
    holed = holed_rule(cfg)
    for _ in range(cfg.max_split_rounds):
        a, e = np.asarray(area), np.asarray(excess)
        e = np.where(np.isfinite(e), e, 1e6)
        if current <= cfg.target_distortion:
            break
        splittable = np.array([len(isl.faces) >= 2 and not fz for isl, fz in zip(islands, frozen)])
        if not splittable.any():
            break
        i = int(np.argmax(np.where(splittable, a * e, -1.0)))
        isl = islands[i]
        for method in ("spectral", "axis") if SPLIT == "spectral" else ("axis",):
            new = flatten_halves(xyz, work_faces[isl.work_faces], isl.work_faces, isl.label, cfg.max_split_depth, st,
                                 method, holed)
            relax_islands(new, cfg)
            slit_islands(new, cfg)
            if zigzag(isl, new):
                continue
            new_area = [float(triangle_areas(n.xyz, n.faces).sum()) for n in new]
            new_excess = [energy_excess(n.xyz, n.uv, n.faces) for n in new]
            candidate = atlas_distortion(islands[:i] + islands[i + 1:] + new)
            # the halves must contribute less, and not blow the atlas up on the way (a half whose
            # SLIM stalls, e.g. a spectral half spanning two thin parts, can reach metric 16)
            if (np.isfinite(new_excess).all() and np.dot(new_area, new_excess) < a[i] * e[i]
                    and candidate <= BLOWUP * current):
                break
        else:
            # the halves are no better (a crease or a sliver, not the lack of a cut, is to blame)
            frozen[i] = True
            st["splits_rejected"] = st.get("splits_rejected", 0) + 1
            continue
        st["islands_split"] += 1
        islands = islands[:i] + islands[i + 1:] + new
        area = area[:i] + area[i + 1:] + new_area
        excess = excess[:i] + excess[i + 1:] + new_excess
        frozen = frozen[:i] + frozen[i + 1:] + [False] * len(new)
        current = candidate
    a, e = np.asarray(area), np.asarray(excess)
    st["mean_excess"] = float((a * e).sum() / a.sum())
    st["distortion_metric"] = atlas_distortion(islands)
    return islands, st


def _principal_axis(uv: np.ndarray, minor: bool = False) -> np.ndarray:
    """Unit principal (or, ``minor``, the other) axis of the points ``uv``."""
    d = uv - uv.mean(0)
    return np.linalg.eigh(d.T @ d)[1][:, 0 if minor else -1]


def _principal_extent(uv: np.ndarray) -> tuple[float, np.ndarray]:
    """(length of ``uv`` along its principal axis, that unit axis)."""
    axis = _principal_axis(uv)
    s = (uv - uv.mean(0)) @ axis
    return float(s.max() - s.min()), axis


def island_parts(islands: list[Island], comp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the part, i.e. connected component, of each island; the number of islands per part)."""
    part = np.array([int(comp[i.work_faces[0]]) for i in islands], dtype=np.int64)
    return part, np.bincount(part, minlength=int(comp.max()) + 1)


def _sub_island(isl: Island, sel: np.ndarray) -> Island:
    vid, inv = np.unique(isl.faces[sel], return_inverse=True)
    return Island(inv.reshape(-1, 3), isl.uv[vid], isl.xyz[vid], isl.work_faces[sel], isl.work_vertex[vid], isl.label)


def _one_piece(adj, mask: np.ndarray) -> bool:
    """Whether the faces ``mask`` of a manifold island are one piece through shared edges
    (hence through shared vertices too), from the island's face adjacency ``adj``
    (:func:`texture.regions.face_adjacency`): an edge of a manifold mesh joins at most two
    faces, so the pairs within the subset are the subset's own adjacency."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = int(mask.sum())
    if n == 0:
        return False
    index = np.cumsum(mask) - 1
    keep = mask[adj.a] & mask[adj.b]
    g = coo_matrix((np.ones(int(keep.sum())), (index[adj.a[keep]], index[adj.b[keep]])), shape=(n, n))
    return connected_components(g, directed=False)[0] == 1


#: a halving whose cut (along mesh edges) is longer than this many times the island's width
#: across it is refused: the mesh has no edges running across there (faces as long as the
#: island, e.g. a tube whose side is one ring of faces spanning its height), and the cut
#: would zigzag up and down their long edges, adding many times the seam a straight cut
#: would. An edge path across a fair triangulation is at most about 1.3x its straight line.
ZIGZAG = 2.0
#: :func:`cut_in_pieces`'s cut lengths this close (relative) are equal, and the tie goes to
#: the position nearest the even one: a cut 1 % shorter saves 1 % of one cut's seam, while
#: moving a piece's end lengthens a row of the stack. Across a strip of even width the cuts
#: differ only by the rounding of the input's float32 coordinates (3e-5 relative on a 100 x 1
#: strip of 0.0137 edges stored 5 away from the origin), which took pieces to 11 and 14 of
#: an even 12.5. (The packing's halvings, compared by their packings, keep exact ties.)
TIE = 0.01
#: cut positions tried by a halving: these fractions of the island's area lie before the cut
#: along its principal axis (:func:`cut_in_pieces` scales them to its pieces).
LONG_CUTS = np.linspace(0.3, 0.7, 9)


#: where :func:`cut_in_pieces` tries each cut, in pieces from its even position: within 10 %
#: of a piece, so that the pieces stack as rows of about one length (the atlas's side is the
#: longest row's; with a halving's window, 40 % either side, a 2.0 x 0.02 ribbon's shortest
#: cuts made pieces of 0.125-0.4), and densely enough that a mesh a dozen faces long a piece
#: still offers cuts along its edges near the even position
PIECE_CUTS = np.linspace(-0.1, 0.1, 17)


def cut_in_pieces(isl: Island, n: int) -> tuple[list[Island], float]:
    """(``isl`` cut across its principal axis into up to ``n`` pieces of about equal area, the
    cuts' 3D length). Cut ``k`` is a :func:`halve_across` of what is left that ends the
    pieces so far at ``k / n`` of the island's area (so that a piece the mesh's edges made a
    little short is made up by the next, not passed on to the last), at the shortest cut
    among :data:`PIECE_CUTS` of that position (ties: the nearest). Where no cut works, the
    pieces made so far and the rest are returned."""
    pieces, length, rest = [], 0.0, isl
    total = float(triangle_areas(isl.xyz, isl.faces).sum())
    done = 0.0  # area of the pieces made
    for k in range(1, n):
        left = total - done
        at = (k * total / n - done) / left  # the position k / n as a fraction of what is left
        spread = PIECE_CUTS * (total / n) / left
        got = halve_across(rest, cuts=at + spread, centre=at, tie=TIE)
        if got is None:
            break
        (first, rest), cut = got
        pieces.append(first)
        length += cut
        done += float(triangle_areas(first.xyz, first.faces).sum())
    return pieces + [rest], length


def halve_across(isl: Island, along: bool = False, cuts=LONG_CUTS, adj=None,
                 centre: float = 0.5, tie: float = 0.0) -> tuple[list[Island], float] | None:
    """(the island cut in two, the cut's 3D length), or None where no cut works.

    The cut runs across the island's principal UV axis (``along``: along it, i.e. across the
    minor axis), along mesh edges, at the position (among ``cuts``: the fraction of the
    island's 3D area before the cut) with the shortest cut (ties, lengths within ``tie`` of
    each other relatively: the one nearest ``centre``, by default the more even halves) whose
    two halves are each one piece; the first half is the one before the cut. The halves keep their UVs: parts of a flip-free,
    overlap-free island stay so, and the input's faces are not changed (an unwrap may only
    cut along edges). ``adj``: the island's face adjacency, when the caller has it."""
    from .regions import face_adjacency

    axis = _principal_axis(isl.uv, minor=along)
    s = isl.uv[isl.faces].mean(1) @ axis
    width = float(np.ptp(isl.uv @ np.array([-axis[1], axis[0]])))  # across the axis: a straight cut's most
    area = triangle_areas(isl.xyz, isl.faces)
    order = np.argsort(s, kind="stable")
    cum = np.cumsum(area[order]) / area.sum()
    adj = face_adjacency(isl.xyz, isl.faces) if adj is None else adj
    best = None
    for q in sorted(cuts, key=lambda q: abs(q - centre)):  # equal cuts: the one nearest the centre
        lo = np.zeros(len(isl.faces), bool)
        lo[order[:int(np.searchsorted(cum, q)) + 1]] = True
        if lo.all() or not (_one_piece(adj, lo) and _one_piece(adj, ~lo)):
            continue
        # a cut between face sets zigzags: its ears move across (the halves keep their UVs),
        # and cuts are compared as they will be
        lo, _ = smooth_cut(isl, lo)
        cut = float(adj.length[lo[adj.a] != lo[adj.b]].sum())
        if cut > ZIGZAG * width:  # no line of the mesh runs across here (long thin faces)
            continue
        if best is None or cut < best[0] * (1.0 - tie):  # a tie keeps the nearer
            best = (cut, lo)
    if best is None:
        return None
    return [_sub_island(isl, np.flatnonzero(best[1])), _sub_island(isl, np.flatnonzero(~best[1]))], best[0]


def may_halve(islands_in_part: int, cfg) -> bool:
    """Whether an island of a part (connected component) holding ``islands_in_part`` islands
    may be halved for its length or for an ordinary packing gain. Never from within
    ``cfg.long_max_islands`` to past it (the island target), and not a part that flattened as
    one island: that is the fewest seams it can have (none on an open, disk-like part), and a
    compact island just over the atlas side costs only a few hundredths of utilisation, less
    than a first seam is worth. Such a part is halved only by the packing search, for
    ``cfg.pack_first_seam_gain`` (:mod:`texture.unwrap_layout`), or for its length where it
    is a strip (:data:`LONE_LONG`). A part already past the cap (its topology or distortion
    took more islands: a genus-6 plate's 9) misses the island target whether it is halved or
    not, so there a halving is judged by its gain alone (that plate: utilisation 0.44 -> 0.65
    for one cut of 0.79)."""
    return 1 < islands_in_part and islands_in_part != cfg.long_max_islands


#: a part that flattened as one island (its fewest seams) is halved for its length only when
#: it is this many times longer than the atlas side. The atlas must be at least as wide as
#: the island is long, so such an island alone caps utilisation below a quarter of
#: ``long_fill`` whatever the packer does: it is a strip (a tube unrolled whole), and the
#: first seam buys several times the utilisation; a compact island just over the side caps
#: it only a little, and stays whole (:func:`may_halve`).
LONE_LONG = 2.0


def split_long_islands(islands: list[Island], comp: np.ndarray, cfg) -> tuple[list[Island], dict]:
    """Cut islands too long to pack densely, longest first, in even pieces or by halvings:
    whichever packs better.

    A square atlas that holds all islands' UV area at utilisation ``cfg.long_fill`` has the
    side ``S = sqrt(area / long_fill)``; an island longer than ``S`` along its principal axis
    forces a lower utilisation whatever the packer does (a strip around a torus's tube set
    the atlas's width, utilisation 0.22). Such an island is cut across that axis, two ways
    (:func:`_cut_long`), and the islands of the one whose first guess
    (:func:`texture.unwrap_layout.guess_layouts`) packs better are kept:

    - *even*: an island ``L`` long in ``ceil(L / S)`` pieces of about equal area
      (:func:`cut_in_pieces`), which stack as rows of one length where the island is a
      straight strip (a 100:1 ribbon: 0.59; halvings left rows of four lengths, 0.24);
    - *halved*: the longest island halved at its shortest cut within 0.3-0.7 of its area,
      again and again while one is too long, which packs better where the island is a curved
      strip, whose even pieces are arcs that do not stack (a Moebius strip: 0.61 halved,
      0.56 in even pieces).

    The UVs are kept, so distortion, flips and overlap do not change; only seams and islands
    are added. At most ``cfg.long_max_splits`` islands are cut (each into as many pieces as
    the way asks; halved: that many halvings), each allowed by :func:`may_halve` (a part
    within ``cfg.long_max_islands`` islands is never taken past it: fewer, longer pieces
    then), or a part's one island longer than ``LONE_LONG`` times the side.
    ``long_islands_split`` counts the cuts (islands added); ``long_cut`` names the way kept.
    """
    st = {"long_islands_split": 0}
    if cfg.long_max_splits <= 0 or not islands:
        return islands, st
    total = sum(float(np.abs(signed_areas(i.uv, i.faces)).sum()) for i in islands)
    side = float(np.sqrt(total / cfg.long_fill))
    st["atlas_side"] = side
    ways = {way: _cut_long(islands, comp, cfg, side, way == "even") for way in ("even", "halved")}
    if len(ways["even"]) == len(islands) and len(ways["halved"]) == len(islands):
        return islands, st
    from .unwrap_layout import guess_layouts  # it packs what this module cuts

    guess = dict(zip(ways, guess_layouts(list(ways.values()), cfg)))
    way = max(ways, key=lambda w: (guess[w], w == "even"))  # a tie: the even pieces
    st.update(long_islands_split=len(ways[way]) - len(islands), long_cut=way,
              long_guess={w: round(float(g), 4) for w, g in guess.items()})
    return ways[way], st


def _cut_long(islands: list[Island], comp: np.ndarray, cfg, side: float, even: bool) -> list[Island]:
    """The islands with those too long for the atlas's ``side`` cut (:func:`split_long_islands`),
    in ``even`` pieces or by halvings."""
    part, per_comp = island_parts(islands, comp)
    per_comp = per_comp.copy()
    skip: set[int] = set()
    def over(isl, p):  # the island's length in units of the longest it may be
        if id(isl) in skip:
            return 0.0
        if may_halve(per_comp[p], cfg):
            return _principal_extent(isl.uv)[0] / side
        if per_comp[p] == 1 < cfg.long_max_islands:  # a part's first seam: only for a strip
            return _principal_extent(isl.uv)[0] / (LONE_LONG * side)
        return 0.0

    for _ in range(cfg.long_max_splits):
        length = [over(isl, p) for isl, p in zip(islands, part)]
        k = int(np.argmax(length))
        c = int(part[k])
        if length[k] <= 1.0:
            break
        if even:
            n = int(np.ceil(_principal_extent(islands[k].uv)[0] / side - 1e-9))
            if per_comp[c] <= cfg.long_max_islands:  # within the island cap: never past it
                n = min(n, cfg.long_max_islands - int(per_comp[c]) + 1)
            pieces = cut_in_pieces(islands[k], max(n, 2))[0]
        else:
            halved = halve_across(islands[k])
            pieces = [islands[k]] if halved is None else halved[0]
        if len(pieces) < 2:
            skip.add(id(islands[k]))
            continue
        if even:
            # the pieces are as even as the mesh's edges allow: one a column over the side is
            # not cut again (a 16 x 1 strip at side 5.8: 5 + 5 + 6, not 5 + 5 + 3 + 3)
            skip.update(id(p) for p in pieces)
        islands = islands[:k] + islands[k + 1:] + pieces
        part = np.concatenate([np.delete(part, k), [c] * len(pieces)])
        per_comp[c] += len(pieces) - 1
    return islands
