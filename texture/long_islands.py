"""Islands too long to pack densely: cut across their length, in even pieces or by halvings.

A square atlas holds the islands at utilisation ``cfg.long_fill`` only if no island is
longer than its side; a strip (a tube unrolled whole, a ribbon, a belt) sets the atlas's
width otherwise. :func:`split_long_islands` cuts such islands (:func:`texture.halving.halve_across`:
along the input's edges, UVs kept) two ways and keeps the one with the shorter cuts unless
the other packs clearly better. Its cuts are straight across the strip (``band=False``): the
shortest cut between two positions may run slanted or bent, and pieces then no longer end
square and stack (measured on the benchmark fits with it: genus2's utilisation 0.576 ->
0.557, pretzel3's 0.620 -> 0.606, the torus 3 -> 4 islands), while the packing's halvings are
compared by their packings and take the shortest (:mod:`texture.unwrap_layout`).
"""
from __future__ import annotations

import numpy as np

from mnacore.triangles import signed_areas, triangle_areas

from .halving import LONE_LONG, _principal_extent, halve_across, island_parts, may_halve
from .unwrap_islands import Island
from .unwrap_layout import guess_layouts

#: :func:`cut_in_pieces`'s cut lengths this close (relative) are equal, and the tie goes to
#: the position nearest the even one: a cut 1 % shorter saves 1 % of one cut's seam, while
#: moving a piece's end lengthens a row of the stack. Across a strip of even width the cuts
#: differ only by the rounding of the input's float32 coordinates (3e-5 relative on a 100 x 1
#: strip of 0.0137 edges stored 5 away from the origin), which took pieces to 11 and 14 of
#: an even 12.5. (The packing's halvings, compared by their packings, keep exact ties.)
TIE = 0.01
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
        # straight cuts (no band): pieces end square to the strip, so they stack as rows
        got = halve_across(rest, cuts=at + spread, centre=at, tie=TIE, band=False)
        if got is None:
            break
        (first, rest), cut = got
        pieces.append(first)
        length += cut
        done += float(triangle_areas(first.xyz, first.faces).sum())
    return pieces + [rest], length


def split_long_islands(islands: list[Island], comp: np.ndarray, cfg) -> tuple[list[Island], dict]:
    """Cut islands too long to pack densely, longest first, in even pieces or by halvings:
    the shorter cuts, unless the other way packs clearly better.

    A square atlas that holds all islands' UV area at utilisation ``cfg.long_fill`` has the
    side ``S = sqrt(area / long_fill)``; an island longer than ``S`` along its principal axis
    forces a lower utilisation whatever the packer does (a strip around a torus's tube set
    the atlas's width, utilisation 0.22). Such an island is cut across that axis, two ways
    (:func:`_cut_long`), and the islands of the one with the shorter cuts are kept unless
    the other's first guess (:func:`texture.unwrap_layout.guess_layouts`) packs better by
    ``cfg.pack_cut_gain``, the gain a cut must buy in the packing search (the guesses are
    rough: limbs' halvings guessed 0.42 against 0.41, and its even pieces, with shorter
    cuts, ended at 0.58 after the search against the halvings' 0.55):

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
    ``long_islands_split`` counts the cuts (islands added); ``long_cut`` names the way kept,
    ``long_guess`` and ``long_cut_length`` give each way's guess and 3D cut length.
    """
    st = {"long_islands_split": 0}
    if cfg.long_max_splits <= 0 or not islands:
        return islands, st
    total = sum(float(np.abs(signed_areas(i.uv, i.faces)).sum()) for i in islands)
    side = float(np.sqrt(total / cfg.long_fill))
    st["atlas_side"] = side
    cuts = {way: _cut_long(islands, comp, cfg, side, way == "even") for way in ("even", "halved")}
    ways = {way: got[0] for way, got in cuts.items()}
    if len(ways["even"]) == len(islands) and len(ways["halved"]) == len(islands):
        return islands, st
    guess = dict(zip(ways, guess_layouts(list(ways.values()), cfg)))
    short, other = sorted(ways, key=lambda w: (cuts[w][1], w != "even"))  # a tie: the even pieces
    way = other if guess[other] >= guess[short] + cfg.pack_cut_gain else short
    st.update(long_islands_split=len(ways[way]) - len(islands), long_cut=way,
              long_guess={w: round(float(g), 4) for w, g in guess.items()},
              long_cut_length={w: round(float(c[1]), 4) for w, c in cuts.items()})
    return ways[way], st


def _cut_long(islands: list[Island], comp: np.ndarray, cfg, side: float, even: bool) -> tuple[list[Island], float]:
    """(The islands with those too long for the atlas's ``side`` cut (:func:`split_long_islands`),
    in ``even`` pieces or by halvings; the cuts' 3D length)."""
    cut_length = 0.0
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
            pieces, cut = cut_in_pieces(islands[k], max(n, 2))
        else:
            halved = halve_across(islands[k], band=False)
            pieces, cut = ([islands[k]], 0.0) if halved is None else halved
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
        cut_length += cut
    return islands, cut_length
