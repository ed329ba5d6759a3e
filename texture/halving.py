"""Halving islands: for distortion (the split stage), for length, and the cut itself.

Three callers cut an island in two: :func:`refine_islands` while the atlas is too distorted
(spectral bisection, re-flattened), :mod:`texture.long_islands` for islands too long to pack
densely, and the packing search (:mod:`texture.unwrap_layout`) for utilisation. The last two
keep the island's UVs (:func:`halve_across`); every cut runs along the input's edges, is the shortest the
positions allow (a minimum cut between them, where the caller does not need straight
cuts), and is refused where it would zigzag (:data:`ZIGZAG`).
"""
from __future__ import annotations

import numpy as np

from mnacore.triangles import triangle_areas

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


def _pieces(adj, mask: np.ndarray) -> tuple[int, np.ndarray]:
    """(how many pieces, the piece of each face of ``mask`` in order) of the faces ``mask`` of
    a manifold island through shared edges (hence through shared vertices too), from the
    island's face adjacency ``adj`` (:func:`texture.regions.face_adjacency`): an edge of a
    manifold mesh joins at most two faces, so the pairs within the subset are the subset's
    own adjacency."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = int(mask.sum())
    if n == 0:
        return 0, np.zeros(0, np.int64)
    index = np.cumsum(mask) - 1
    keep = mask[adj.a] & mask[adj.b]
    g = coo_matrix((np.ones(int(keep.sum())), (index[adj.a[keep]], index[adj.b[keep]])), shape=(n, n))
    return connected_components(g, directed=False)


def _one_piece(adj, mask: np.ndarray) -> bool:
    """Whether the faces ``mask`` of a manifold island are one piece (:func:`_pieces`)."""
    return _pieces(adj, mask)[0] == 1


def _largest_piece(adj, mask: np.ndarray, area: np.ndarray) -> np.ndarray:
    """The faces of ``mask``'s largest piece (3D area, :func:`_pieces`); ``mask`` itself where
    it is one piece or none."""
    n, piece = _pieces(adj, mask)
    if n <= 1:
        return mask
    out = np.zeros_like(mask)
    out[np.flatnonzero(mask)[piece == np.argmax(np.bincount(piece, weights=area[mask]))]] = True
    return out


#: a halving whose cut (along mesh edges) is longer than this many times the island's width
#: across it is refused: the mesh has no edges running across there (faces as long as the
#: island, e.g. a tube whose side is one ring of faces spanning its height), and the cut
#: would zigzag up and down their long edges, adding many times the seam a straight cut
#: would. An edge path across a fair triangulation is at most about 1.3x its straight line.
ZIGZAG = 2.0
#: cut positions tried by a halving: these fractions of the island's area lie before the cut
#: along its principal axis
LONG_CUTS = np.linspace(0.3, 0.7, 9)


#: the most faces a band cut's minimum cut runs over (its band is narrowed about its middle
#: above), for time: scipy's maximum flow grows faster than the faces it runs over (about
#: 0.1 s at 20,000 here), and the packing search makes up to 18 halvings a round. A band is
#: 15-40 % of its island, so only islands above 50,000 faces are narrowed, and there the
#: band still reaches 20,000 / sqrt(F) faces deep across an island about sqrt(F) faces wide
#: (30 at 400,000): room for the cut to run straight on the surface, not for a neck far off.
BAND_MAX_FACES = 20_000
#: an end of a band cut in pieces is held by its largest only where that holds at least this
#: share of the end's area: a few lobes (a fork's two prongs: a half each; forked ends of
#: relaxed islands: 0.55-1.0), not a scatter of faces. Where faces span the whole band (a
#: tube's side of one row of faces as tall as it), the ends are single faces that their
#: centroids interleave, 1/n of the end each, and holding one would let the cut run anywhere.
LOBE_SHARE = 1.0 / 3.0
#: a band cut's edges weigh ``1 + CENTRE_BIAS * d`` times their length, ``d`` their distance
#: (area fraction) from the centre: a tie-break (a cut at most 0.1 % longer may win), not a preference
CENTRE_BIAS = 1e-3


def _band_cut(isl: Island, adj, pos: np.ndarray, lo_q: float, hi_q: float, width: float,
              centre: float, area: np.ndarray) -> tuple[float, np.ndarray] | None:
    """(3D length, faces before it) of the shortest cut between the positions ``lo_q`` and
    ``hi_q`` (``pos``: each face's area fraction along the axis, ``area`` its 3D area): a
    minimum cut of the faces between them (:func:`texture.borders.min_cut_labels`), those
    before held to the first half and those after to the second, its ears then moved; None
    where a half is not one piece or the cut zigzags (:data:`ZIGZAG`).

    An island's end need not be one piece: past a position across a U-shaped or forked
    island lie two lobes, and holding both to one half asks the cut to join what only the
    band can join (the half then comes out in pieces, and only a straight cut was left).
    So where the halves come out in pieces and an end is in pieces, only the largest piece
    of each such end is held, and the cut places the smaller lobes, like the band's faces,
    wherever it is shortest. (Where holding whole ends leaves whole halves, they stay held:
    freeing their lobes on every halving offered the packing search cuts that pack better
    but run longer, and its rounds took them: seams rose on 3 of 19 benchmark fits.)"""
    from .borders import min_cut_labels

    free = (pos > lo_q) & (pos <= hi_q)
    count = int(free.sum())
    if count > BAND_MAX_FACES:  # narrowed about its middle to hold about that many faces
        mid, half = 0.5 * (lo_q + hi_q), 0.5 * (hi_q - lo_q) * BAND_MAX_FACES / count
        lo_q, hi_q = mid - half, mid + half
        free = (pos > lo_q) & (pos <= hi_q)
    label = (pos > lo_q).astype(np.int64)  # held: 0 before the first position, 1 after the last
    # of cuts of equal length, the one nearest ``centre`` (a flat strip's cuts across are all
    # equal, and the bare minimum cut is the one nearest the first position: uneven halves)
    weight = 1.0 + CENTRE_BIAS * np.abs(0.5 * (pos[adj.a] + pos[adj.b]) - centre)
    lo = min_cut_labels(label, free, adj, 0, 1, weight) == 0
    if not (_one_piece(adj, lo) and _one_piece(adj, ~lo)):  # (an empty half is no piece)
        lobed = False
        for end in (pos <= lo_q, pos > hi_q):  # an end's smaller lobes go free
            held = _largest_piece(adj, end, area)
            if held is end:  # one piece (or none)
                continue
            if area[held].sum() < LOBE_SHARE * area[end].sum():
                return None  # not lobes: a scatter of faces (see LOBE_SHARE)
            free |= end & ~held
            lobed = True
        if not lobed:
            return None
        lo = min_cut_labels(label, free, adj, 0, 1, weight) == 0
        if not (_one_piece(adj, lo) and _one_piece(adj, ~lo)):
            return None
    lo, _ = smooth_cut(isl, lo)
    cut = float(adj.length[lo[adj.a] != lo[adj.b]].sum())
    return (cut, lo) if cut <= ZIGZAG * width else None


def halve_across(isl: Island, along: bool = False, cuts=LONG_CUTS, adj=None,
                 centre: float = 0.5, tie: float = 0.0, band: bool = True) -> tuple[list[Island], float] | None:
    """(the island cut in two, the cut's 3D length), or None where no cut works.

    The cut runs across the island's principal UV axis (``along``: along it, i.e. across the
    minor axis), along mesh edges, whose two halves are each one piece (the first half is the
    one before the cut):

    - ``band``: the shortest cut anywhere between the first and the last of the positions
      ``cuts`` (fractions of the island's 3D area before the cut along the axis), a minimum
      cut (:func:`texture.borders.min_cut_labels`) of the faces between them, the faces
      before the first held to one half and those after the last to the other. A straight
      cut follows a line of the flattened map, which is not a short line on the surface (a
      cap's map bends its geodesics), and it steps over a neck that lies between two
      positions; before ears move, the minimum cut is never longer than any straight cut
      between them (the packing's halvings: the sphere's 2.05 -> 1.71, bob's 1.80 -> 1.10).
      Not for cuts meant to leave pieces of one length that stack (:mod:`texture.long_islands`);
    - straight, where there is no band cut (one position, ``band=False``, or halves not one
      piece): the shortest of the cuts at the positions ``cuts`` (ties, lengths within ``tie``
      of each other relatively: the one nearest ``centre``, by default the more even halves).

    The halves keep their UVs: parts of a flip-free, overlap-free island stay so, and the
    input's faces are not changed (an unwrap may only cut along edges). ``adj``: the
    island's face adjacency, when the caller has it."""
    from .regions import face_adjacency

    axis = _principal_axis(isl.uv, minor=along)
    s = isl.uv[isl.faces].mean(1) @ axis
    width = float(np.ptp(isl.uv @ np.array([-axis[1], axis[0]])))  # across the axis: a straight cut's most
    area = triangle_areas(isl.xyz, isl.faces)
    order = np.argsort(s, kind="stable")
    cum = np.cumsum(area[order]) / area.sum()
    adj = face_adjacency(isl.xyz, isl.faces) if adj is None else adj
    pos = np.empty(len(area))
    pos[order] = cum  # each face's fraction of the area up to and including it
    lo_q, hi_q = float(np.min(cuts)), float(np.max(cuts))
    shortest = _band_cut(isl, adj, pos, lo_q, hi_q, width, centre, area) if band and hi_q > lo_q else None
    # straight cuts: all where no band cut was made (of equal cuts, the one nearest the
    # centre), else only the one nearest the centre, kept where the band cut is no shorter
    # (it leaves the most even halves). No straight cut between the
    # positions is shorter than the band cut before ears move, and each costs its ears'
    # moves and two connectivity tests (at 1M faces, seconds), so the others are not tried.
    straight = sorted(cuts, key=lambda q: abs(q - centre))
    best = None
    for q in straight if shortest is None else straight[:1]:
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
    if shortest is not None and (best is None or best[0] > shortest[0] * (1.0 + 1e-9)):
        best = shortest
    if best is None:
        return None
    return [_sub_island(isl, np.flatnonzero(best[1])), _sub_island(isl, np.flatnonzero(~best[1]))], best[0]


def may_halve(islands_in_part: int, cfg) -> bool:
    """Whether an island of a part (connected component) holding ``islands_in_part`` islands
    may be halved for its length or for an ordinary packing gain. Never from within
    ``cfg.long_max_islands`` to past it (the island target), and not a part that flattened as
    one island: that is the fewest seams it can have (none on an open, disk-like part), and a
    compact island just over the atlas side costs only a few hundredths of utilisation, less
    than a first seam is worth. Such a part, and one at the cap, is halved only by the packing
    search, for ``cfg.pack_first_seam_gain`` (:mod:`texture.unwrap_layout`: at the cap, an
    island as long as the atlas (a genus-6 plate's rim unrolled, utilisation 0.19) would
    otherwise stay whole), or a one-island part for its length where it is a strip
    (:data:`LONE_LONG`, :mod:`texture.long_islands`). A part already past the cap (its
    topology or distortion took more islands: a genus-6 plate's 9) misses the island target
    whether it is halved or not, so there a halving is judged by its gain alone (that plate:
    utilisation 0.44 -> 0.65 for one cut of 0.79)."""
    return 1 < islands_in_part and islands_in_part != cfg.long_max_islands


#: a part that flattened as one island (its fewest seams) is halved for its length only when
#: it is this many times longer than the atlas side. The atlas must be at least as wide as
#: the island is long, so such an island alone caps utilisation below a quarter of
#: ``long_fill`` whatever the packer does: it is a strip (a tube unrolled whole), and the
#: first seam buys several times the utilisation; a compact island just over the side caps
#: it only a little, and stays whole (:func:`may_halve`).
LONE_LONG = 2.0
