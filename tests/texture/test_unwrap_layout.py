"""The unwrap's packing search (:mod:`texture.unwrap_layout`): turns and halvings."""
from __future__ import annotations

import numpy as np
import pytest

from mnacore.triangles import signed_areas
from texture.layout_packing import (
    EXHAUSTIVE_TURN_ISLANDS,
    TURN_PASSES,
    TURNED_ISLANDS,
    _turn_sets,
    island_arrays,
    min_rect_rotation,
    quarter_turn,
)
from texture.unwrap import UnwrapConfig
from texture.unwrap_islands import Island
from texture.unwrap_layout import choose_layout
from texture.verify import verify_packing


def _grid_island(nx: int, ny: int, cell: float = 1.0) -> Island:
    """A flat nx-by-ny grid of ``cell``-sized cells (UV = xy, isometric), counter-clockwise."""
    x, y = np.meshgrid(np.arange(nx + 1) * cell, np.arange(ny + 1) * cell, indexing="xy")
    uv = np.column_stack([x.ravel(), y.ravel()])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    a = (j * (nx + 1) + i).ravel()
    faces = np.concatenate([np.column_stack([a, a + 1, a + nx + 2]), np.column_stack([a, a + nx + 2, a + nx + 1])])
    return Island(faces, uv, np.column_stack([uv, np.zeros(len(uv))]), np.arange(len(faces)), np.arange(len(uv)), 0)


def test_min_rect_rotation_turns_a_tilted_rectangle_to_the_axes_without_mirroring():
    """A 4 x 1 rectangle tilted by 30 degrees: after the turn its bounding box is the
    rectangle itself (area 4, not the tilted box's 11.4), long side along u, det +1."""
    t = np.radians(30)
    rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    uv = _grid_island(8, 2, 0.5).uv @ rot.T
    r = min_rect_rotation(uv)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert np.ptp(uv, 0).prod() == pytest.approx(11.36, abs=0.01)
    ext = np.ptp(uv @ r.T, 0)
    assert ext == pytest.approx([4.0, 1.0], abs=1e-9)
    assert np.array_equal(min_rect_rotation(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])), np.eye(2))


def test_a_long_strip_is_halved_for_packing_keeping_one_scale_and_no_mirror():
    """One 4 x 1 island packs at about a quarter of a square; halved across its length, its
    two 2 x 1 halves fill most of it. The halves keep their UVs up to a rotation and one shared
    scale (every packed edge has the same length ratio to its 3D length), run counter-clockwise,
    and do not overlap."""
    strip, small = _pair()
    comp = np.zeros(len(strip.faces) + len(small.faces), np.int64)  # one part, two islands
    cfg = UnwrapConfig(resolution=512, padding=4)
    plain = choose_layout([strip, small], comp, UnwrapConfig(resolution=512, padding=4, pack_max_cuts=0))
    got = choose_layout([strip, small], comp, cfg)
    assert len(plain.islands) == 2 and plain.packing.utilization < 0.3
    assert len(got.islands) == 3 and got.packing.utilization > 0.6
    assert got.stats["halvings"][0]["cut_length"] == pytest.approx(1.0)
    uv, faces, island = island_arrays(got.islands)
    px = got.packing.uv
    xyz = np.concatenate([isl.xyz for isl in got.islands])
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    ratio = np.linalg.norm(px[e[:, 0]] - px[e[:, 1]], axis=1) / np.linalg.norm(xyz[e[:, 0]] - xyz[e[:, 1]], axis=1)
    assert ratio == pytest.approx(np.full(len(ratio), ratio[0]), rel=1e-9)  # one texel density, rigid
    assert (signed_areas(px, faces) > 0).all()  # never mirrored
    assert verify_packing(px, faces, island, 512)[0] == 0
    work = np.sort(np.concatenate([isl.work_faces for isl in got.islands]))
    assert np.array_equal(work, np.arange(len(comp)))  # every face once, none added


def _pair() -> tuple[Island, Island]:
    """A 4 x 1 strip and a small square island of the same part (working faces numbered on)."""
    strip = _grid_island(16, 4, 0.25)
    small = _grid_island(1, 1, 0.25)
    small = Island(small.faces, small.uv, small.xyz + [10.0, 0.0, 0.0], small.work_faces + len(strip.faces),
                   small.work_vertex + len(strip.uv), 1)
    return strip, small


def test_a_part_that_flattened_whole_gets_its_first_seam_only_for_a_large_gain():
    """The same strip as the only island of its part: halving it is its first seam, kept only
    when it gains ``pack_first_seam_gain`` (here it gains about 0.65: kept at the default 0.1,
    refused at 0.8)."""
    strip = _grid_island(16, 4, 0.25)
    comp = np.zeros(len(strip.faces), np.int64)
    got = choose_layout([strip], comp, UnwrapConfig(resolution=512, padding=4))
    gain = got.packing.utilization - got.stats["utilization_uncut"]
    assert len(got.islands) == 2 and [h["first_seam"] for h in got.stats["halvings"]] == [True] and gain > 0.5
    kept = choose_layout([strip], comp, UnwrapConfig(resolution=512, padding=4, pack_first_seam_gain=0.8))
    assert len(kept.islands) == 1 and kept.stats["halvings"] == [] and kept.packing.utilization < 0.3


def test_no_halving_at_the_target_and_past_the_island_cap_only_for_a_large_gain():
    """A layout that already packs ``pack_target`` is not cut (a cut adds seam). A component
    that holds ``long_max_islands`` islands is cut past that target only for
    ``pack_first_seam_gain``, as a part's first seam: the 4 x 1 strip beside a small island
    (about 0.25 uncut, over 0.6 halved) is halved at the default 0.1 and kept whole at 0.8."""
    square = _grid_island(4, 4, 0.25)
    comp = np.zeros(len(square.faces), np.int64)
    got = choose_layout([square], comp, UnwrapConfig(resolution=512, padding=4))
    assert len(got.islands) == 1 and got.packing.utilization > 0.6 and got.stats["halvings"] == []
    strip, small = _pair()
    comp = np.zeros(len(strip.faces) + len(small.faces), np.int64)
    capped = choose_layout([strip, small], comp, UnwrapConfig(resolution=512, padding=4, long_max_islands=2,
                                                              pack_first_seam_gain=0.8))
    assert len(capped.islands) == 2 and capped.stats["halvings"] == [] and capped.packing.utilization < 0.3
    paid = choose_layout([strip, small], comp, UnwrapConfig(resolution=512, padding=4, long_max_islands=2))
    gain = paid.packing.utilization - paid.stats["utilization_uncut"]
    assert len(paid.islands) == 3 and [h["first_seam"] for h in paid.stats["halvings"]] == [True] and gain > 0.3


def test_a_part_already_past_the_island_cap_is_halved_on_gain_alone():
    """The same two islands with a cap of 1: the part is past it whether the strip is halved
    or not (the island target is missed either way), so the halving is judged by its gain,
    as below the cap; with the cap at 2 it stays refused (the test above)."""
    strip, small = _pair()
    comp = np.zeros(len(strip.faces) + len(small.faces), np.int64)
    free = choose_layout([strip, small], comp, UnwrapConfig(resolution=512, padding=4))
    past = choose_layout([strip, small], comp, UnwrapConfig(resolution=512, padding=4, long_max_islands=1))
    assert len(free.stats["halvings"]) >= 1 and free.packing.utilization > free.stats["utilization_uncut"] + 0.02
    assert len(past.islands) == len(free.islands) and past.packing.utilization == pytest.approx(free.packing.utilization)


def _comb(teeth: int = 4, height: int = 8, cell: float = 0.25) -> Island:
    """A comb: a 3-cell-high back with ``teeth`` 3-cell-wide teeth ``height`` cells long,
    4 cells apart (a flat grid island with cells removed, UV = xy)."""
    mask = np.zeros((height, teeth * 7 - 4), bool)
    mask[:3] = True
    for t in range(teeth):
        mask[:, 7 * t:7 * t + 3] = True
    g = _grid_island(mask.shape[1], mask.shape[0], cell)
    faces = g.faces[np.tile(mask.ravel(), 2)]  # the grid's two triangles per cell, in two blocks
    vid, inv = np.unique(faces, return_inverse=True)
    faces = inv.reshape(-1, 3)
    return Island(faces, g.uv[vid], g.xyz[vid], np.arange(len(faces)), np.arange(len(vid)), 0)


def _comb_and_small() -> tuple[tuple[Island, Island], np.ndarray]:
    """The comb of four teeth 10 cells long and a small island of its part, and the part."""
    comb = _comb(teeth=4, height=10)
    _, small = _pair()
    small = Island(small.faces, small.uv, small.xyz, np.arange(len(small.faces)) + len(comb.faces),
                   np.arange(len(small.uv)) + len(comb.uv), 1)
    return (comb, small), np.zeros(len(comb.faces) + len(small.faces), np.int64)


def test_halvings_go_on_while_each_pays_until_the_target():
    """A comb of four long teeth (with a small island of its part) needs three halvings, each
    gaining more than ``pack_cut_gain``, to pack 0.6: at most two leave it below the target;
    by default it gets the third and reaches it. (Teeth 8 cells long needed three while the
    cuts were straight; the shortest cuts, between the teeth, get there in two.)"""
    (comb, small), comp = _comb_and_small()
    two = choose_layout([comb, small], comp, UnwrapConfig(resolution=512, padding=4, pack_max_cuts=2))
    got = choose_layout([comb, small], comp, UnwrapConfig(resolution=512, padding=4))
    assert len(two.stats["halvings"]) == 2 and two.packing.utilization < 0.6
    steps = [got.stats["utilization_uncut"]] + [h["utilization"] for h in got.stats["halvings"]]
    assert len(steps) == 4 and (np.diff(steps) >= 0.02).all() and got.packing.utilization >= 0.6
    assert len(got.islands) == 5
    _, faces, island = island_arrays(got.islands)
    assert verify_packing(got.packing.uv, faces, island, 512)[0] == 0


def test_the_search_notes_each_step_as_it_starts_and_chooses_the_same():
    """The packing search's notes (``mna unwrap``'s bar text): the comb above takes three
    halving rounds (the third falls short), then the quarter turns, the halving that fell
    short quarter-turned and the exhaustive placement, each noted as it starts, with the
    utilisation it starts from; with the notes taken, it chooses what it chooses without."""
    (comb, small), comp = _comb_and_small()
    cfg = UnwrapConfig(resolution=512, padding=4)
    notes: list[str] = []
    got = choose_layout([comb, small], comp, cfg, note=notes.append)
    quiet = choose_layout([comb, small], comp, cfg)
    steps = [got.stats["utilization_uncut"]] + [h["utilization"] for h in got.stats["halvings"]]
    assert [n.split(":")[0] for n in notes] == ["pack round 1", "pack round 2", "pack round 3"] + ["pack"] * 3
    assert notes[:3] == [f"pack round {r + 1}: utilisation {u:.2f}, {r + 2} islands" for r, u in enumerate(steps[:3])]
    assert notes[3] == f"pack: quarter turns (utilisation {got.stats['utilization_turned_as_xatlas']:.2f})"
    assert notes[4] == "pack: the last halving, quarter-turned"
    assert notes[5] == f"pack: exhaustive placement (utilisation {got.stats['utilization_before_brute']:.2f})"
    assert got.stats["halvings"][-1].get("after_quarter_turns")
    assert got.packing.utilization == quiet.packing.utilization
    assert np.array_equal(got.packing.uv, quiet.packing.uv)


def _right_triangle(n: int, cell: float, k: int, ny: int | None = None) -> Island:
    """The lower-left half of an n-by-``ny`` grid of ``cell``-sized cells (the cells whose centres
    lie below its hypotenuse): a right triangle, legs ``n * cell`` and ``ny * cell`` (isosceles
    where ``ny`` is None), as island ``k`` (working faces and vertices numbered from ``k`` times
    its size)."""
    ny = n if ny is None else ny
    g = _grid_island(n, ny, cell)
    c = g.uv[g.faces].mean(1)
    faces = g.faces[c[:, 0] / (n * cell) + c[:, 1] / (ny * cell) < 1]
    vid, inv = np.unique(faces, return_inverse=True)
    faces = inv.reshape(-1, 3)
    return Island(faces, g.uv[vid], g.xyz[vid] + [5.0 * k, 0.0, 0.0], np.arange(len(faces)) + k * len(faces),
                  np.arange(len(vid)) + k * len(vid), k)


def test_quarter_turn_is_an_exact_rotation_about_the_centroid():
    """One quarter turn takes u to v about the UV centroid; four give the island back (to rounding);
    faces keep their winding (a rotation, not a mirror)."""
    isl = _right_triangle(4, 0.25, 0)
    c = isl.uv.mean(0)
    one = quarter_turn(isl, 1)
    d = isl.uv - c
    assert np.array_equal(one.uv - c, np.column_stack([-d[:, 1], d[:, 0]]))
    assert np.allclose(quarter_turn(one, 3).uv, isl.uv, rtol=0, atol=1e-15)
    assert quarter_turn(isl, 4) is isl
    assert signed_areas(quarter_turn(isl, 2).uv, isl.faces) == pytest.approx(signed_areas(isl.uv, isl.faces))


def test_two_right_triangles_turned_half_a_turn_apart_pack_as_a_square():
    """Two equal right isosceles triangles fill a square only when one is turned half a turn
    against the other. Turned as xatlas turns them they pack below 0.5; the quarter-turn search
    finds the square (about 0.8 with the gutters at 256 texels, 0.5 being the most two
    triangles side by side in one turn can fill): rigidly, unmirrored, without overlap."""
    tris = [_right_triangle(8, 0.125, 0), _right_triangle(8, 0.125, 1)]
    comp = np.repeat([0, 1], len(tris[0].faces))  # two parts: no halving would be allowed anyway
    got = choose_layout(tris, comp, UnwrapConfig(resolution=256, padding=4, pack_max_cuts=0))
    assert got.stats["utilization_turned_as_xatlas"] < 0.5
    assert got.packing.utilization > 0.75
    uv, faces, island = island_arrays(got.islands)
    px = got.packing.uv
    assert (signed_areas(px, faces) > 0).all()
    assert verify_packing(px, faces, island, 256)[0] == 0
    # the right-angle corners (each grid's uv (0, 0)) sit at opposite corners of the square
    offsets = np.cumsum([0] + [len(t.uv) for t in got.islands])
    right = [px[offsets[k] + int(np.argmin(np.linalg.norm(tris[k].uv, axis=1)))] for k in range(2)]
    assert np.abs(right[0] - right[1]) == pytest.approx(np.ptp(px, axis=0), rel=0.05)


def test_turn_sets_are_all_guessed_for_few_islands_and_searched_one_island_at_a_time_for_many():
    """Up to EXHAUSTIVE_TURN_ISLANDS islands every set is guessed; above, the one-at-a-time
    search guesses at most 1 + 12 * TURN_PASSES sets and finds the best of a score that adds up
    over the islands (each island's best turn, whatever the others'), and turns nothing
    without a gain."""
    big = np.arange(TURNED_ISLANDS)
    want = (2, 1, 3, 0)
    calls = []

    def guess(keys):
        calls.extend(keys)
        return [0.5 - 0.01 * sum((q - w) % 4 for q, w in zip(k, want)) for k in keys]

    every = _turn_sets(big, EXHAUSTIVE_TURN_ISLANDS, guess)
    assert len(every) == 4 ** TURNED_ISLANDS == len(calls)
    calls.clear()
    some = _turn_sets(big, EXHAUSTIVE_TURN_ISLANDS + 1, guess)
    assert len(calls) == len(some) <= 1 + 12 * TURN_PASSES
    assert max(some, key=some.get) == want and some[want] == pytest.approx(0.5)
    flat = _turn_sets(big, EXHAUSTIVE_TURN_ISLANDS + 1, lambda keys: [0.5] * len(keys))
    assert len(flat) == 1 + 3 * TURNED_ISLANDS  # each island's other three turns, guessed once


def test_many_islands_still_find_the_turn_that_nests_two_large_ones():
    """The two right triangles of the test above plus eight small squares (ten islands: the
    one-at-a-time search): the half turn that makes the triangles a square is one island's
    turn, and the search finds it (xatlas's own turns pack the set below 0.5)."""
    tris = [_right_triangle(8, 0.125, 0), _right_triangle(8, 0.125, 1)]
    squares = []
    for k in range(2, 10):
        g = _grid_island(2, 2, 0.06)
        nf, nv = len(g.faces), len(g.uv)
        squares.append(Island(g.faces, g.uv, g.xyz + [5.0 * k, 0.0, 0.0], np.arange(nf) + 1000 * k,
                              np.arange(nv) + 1000 * k, k))
    islands = tris + squares
    assert len(islands) > EXHAUSTIVE_TURN_ISLANDS
    comp = np.repeat(np.arange(len(islands)), [len(i.faces) for i in islands])
    got = choose_layout(islands, comp, UnwrapConfig(resolution=256, padding=4, pack_max_cuts=0))
    assert got.stats["utilization_turned_as_xatlas"] < 0.5
    assert got.packing.utilization > 0.6
    uv, faces, island = island_arrays(got.islands)
    assert (signed_areas(got.packing.uv, faces) > 0).all()
    assert verify_packing(got.packing.uv, faces, island, 256)[0] == 0


def test_a_halving_that_falls_short_is_kept_when_it_pays_quarter_turned(monkeypatch):
    """A comb with a speck of its part, halved by straight cuts: two halvings pay as xatlas
    turns the islands, the third does not (it gains under 0.02 there), and the quarter-turned
    four islands stay below 0.6. Quarter-turned, the third halving gains more than
    ``pack_cut_gain`` over them and is kept: five islands reach the target. Where the gain it
    must buy is higher (0.08), the search stops after the first halving and nothing that falls
    short is kept. (The rule under test is the search's; the shortest cuts, between the
    teeth, pay at once on this comb and on every comb of 3-6 teeth 5-12 cells long tried.)"""
    import texture.unwrap_layout as layout
    from texture.halving import halve_across

    monkeypatch.setattr(layout, "halve_across", lambda *a, **k: halve_across(*a, **k, band=False))
    # nor protrusion cuts: a half comb's tooth cut off pays in the rounds themselves (0.62)
    monkeypatch.setattr(layout, "spike_cuts", lambda *a, **k: [])
    comb = _comb()
    speck = _grid_island(1, 1, 0.02)
    speck = Island(speck.faces, speck.uv, speck.xyz + [5.0, 0.0, 0.0], np.arange(len(speck.faces)) + len(comb.faces),
                   np.arange(len(speck.uv)) + len(comb.uv), 1)
    comp = np.zeros(len(comb.faces) + len(speck.faces), np.int64)
    got = choose_layout([comb, speck], comp, UnwrapConfig(resolution=512, padding=4))
    steps = got.stats["halvings"]
    assert [bool(h.get("after_quarter_turns")) for h in steps] == [False, False, True]
    assert got.stats["utilization_turned_as_xatlas"] < 0.6 <= got.packing.utilization
    assert got.packing.utilization >= got.stats["utilization_turned_as_xatlas"] + 0.02
    assert len(got.islands) == 5
    uv, faces, island = island_arrays(got.islands)
    assert (signed_areas(got.packing.uv, faces) > 0).all()
    assert verify_packing(got.packing.uv, faces, island, 512)[0] == 0
    strict = choose_layout([comb, speck], comp, UnwrapConfig(resolution=512, padding=4, pack_cut_gain=0.08))
    assert len(strict.islands) == 3 and not any(h.get("after_quarter_turns") for h in strict.stats["halvings"])
    assert strict.packing.utilization < 0.6


def _delivered(got, cfg) -> None:
    """The chosen layout as delivered: every face once, none mirrored, no overlap."""
    uv, faces, island = island_arrays(got.islands)
    assert (signed_areas(got.packing.uv, faces) > 0).all()
    assert verify_packing(got.packing.uv, faces, island, cfg.resolution)[0] == 0
    work = np.sort(np.concatenate([isl.work_faces for isl in got.islands]))
    assert np.array_equal(work, np.arange(len(work)))


def test_a_first_seam_that_pays_only_quarter_turned_is_made_alone():
    """A 12 x 9-cell right triangle, one part flattened whole (about 0.44). As xatlas turns the
    halves no single first seam gains ``pack_first_seam_gain``; quarter-turned (as the layout
    is delivered) its best one does, and that one cut reaches the target: two islands, where
    judging it before the turns left two cuts at once to do it (three islands). With the gain
    it must buy above what it gains, nothing is cut this way."""
    tri = _right_triangle(12, 0.25, 0, 9)
    comp = np.zeros(len(tri.faces), np.int64)
    cfg = UnwrapConfig(resolution=512, padding=4)
    got = choose_layout([tri], comp, cfg)
    steps = got.stats["halvings"]
    assert [(h["first_seam"], bool(h.get("after_quarter_turns")), bool(h.get("paired"))) for h in steps] == [
        (True, True, False)]
    assert len(got.islands) == 2
    assert got.stats["utilization_turned_as_xatlas"] == pytest.approx(got.stats["utilization_uncut"])  # no round cut
    assert got.packing.utilization >= max(cfg.pack_target, got.stats["utilization_uncut"] + cfg.pack_first_seam_gain)
    _delivered(got, cfg)
    gain = got.packing.utilization - got.stats["utilization_uncut"]
    strict = choose_layout([tri], comp, UnwrapConfig(resolution=512, padding=4, pack_first_seam_gain=gain + 0.01))
    assert not any(h.get("after_quarter_turns") for h in strict.stats["halvings"])


def test_two_cuts_at_once_are_judged_quarter_turned():
    """A 16 x 16-cell right isosceles triangle, one part flattened whole (about 0.53): no single
    halving pays, quarter-turned or not, and no pair gains what two cuts must buy as xatlas
    turns the pieces; quarter-turned, as delivered, the chosen pair does (three islands)."""
    tri = _right_triangle(16, 0.25, 0)
    comp = np.zeros(len(tri.faces), np.int64)
    cfg = UnwrapConfig(resolution=512, padding=4)
    got = choose_layout([tri], comp, cfg)
    steps = got.stats["halvings"]
    assert len(got.islands) == 3 and [bool(h.get("paired")) for h in steps] == [True, True]
    need = sum(cfg.pack_first_seam_gain if h["first_seam"] else cfg.pack_cut_gain for h in steps)
    assert got.packing.utilization >= got.stats["utilization_uncut"] + need
    assert got.packing.utilization >= cfg.pack_target
    _delivered(got, cfg)


def _two_strips(cells: int = 24) -> tuple[list[Island], np.ndarray]:
    """Two like 6 x 1 strips, each the only island of its own part."""
    a = _grid_island(cells, 4, 0.25)
    b = _grid_island(cells, 4, 0.25)
    b = Island(b.faces, b.uv, b.xyz + [0.0, 5.0, 0.0], b.work_faces + len(a.faces), b.work_vertex + len(a.uv), 1)
    comp = np.repeat([0, 1], len(a.faces))
    return [a, b], comp


def test_two_cuts_that_pay_only_together_are_made_together():
    """Two 6 x 1 strips stack as 6 x 2 in a 6 x 6 square (utilisation about a third); halving
    one leaves the stack 6 wide (no gain), halving both gives four 3 x 1 strips that stack as
    3 x 4 in a 4 x 4 square (about 0.75). Each cut is a part's first seam, so the pair must
    buy twice ``pack_first_seam_gain``; with room for one cut only, no cut is made."""
    islands, comp = _two_strips()
    cfg = UnwrapConfig(resolution=512, padding=4)
    plain = choose_layout(islands, comp, UnwrapConfig(resolution=512, padding=4, pack_max_cuts=0))
    one = choose_layout(islands, comp, UnwrapConfig(resolution=512, padding=4, pack_max_cuts=1))
    got = choose_layout(islands, comp, cfg)
    assert plain.packing.utilization < 0.4 and len(one.islands) == 2 and one.stats["halvings"] == []
    assert len(got.islands) == 4 and got.packing.utilization > 0.6
    assert got.packing.utilization >= plain.packing.utilization + 2 * cfg.pack_first_seam_gain
    halvings = got.stats["halvings"]
    assert [(h["paired"], h["first_seam"], h["at"]) for h in halvings] == [(True, True, "middle")] * 2
    assert [h["cut_length"] for h in halvings] == pytest.approx([1.0, 1.0])  # straight across the 1-wide strips
    uv, faces, island = island_arrays(got.islands)
    assert (signed_areas(got.packing.uv, faces) > 0).all()
    assert verify_packing(got.packing.uv, faces, island, 512)[0] == 0
    work = np.sort(np.concatenate([isl.work_faces for isl in got.islands]))
    assert np.array_equal(work, np.arange(len(comp)))


def test_a_pair_must_buy_what_both_cuts_cost():
    """The same strips with a first seam worth more than half the pair's gain: no pair."""
    islands, comp = _two_strips()
    got = choose_layout(islands, comp, UnwrapConfig(resolution=512, padding=4, pack_first_seam_gain=0.25))
    assert len(got.islands) == 2 and got.stats["halvings"] == []


def _disc(cells: int, shift: float, first_face: int, first_vertex: int, label: int) -> Island:
    """A flat disc island: the cells of a ``cells`` x ``cells`` grid (0.25 each) whose centres
    lie inside its inscribed circle."""
    g = _grid_island(cells, cells, 0.25)
    r = cells * 0.125
    f = g.faces[np.linalg.norm(g.uv[g.faces].mean(1) - r, axis=1) < r]
    vid, inv = np.unique(f, return_inverse=True)
    uv = g.uv[vid]
    return Island(inv.reshape(-1, 3), uv, np.column_stack([uv + [shift, 0.0], np.zeros(len(uv))]),
                  np.arange(len(f)) + first_face, np.arange(len(uv)) + first_vertex, label)


def test_the_chosen_layout_is_kept_or_bettered_by_an_exhaustive_placement():
    """Four round islands (diameters 2, 1.5, 1, 1): xatlas's exhaustive placement
    (``bruteForce``), tried once on the chosen layout, packs them tighter than its default
    placement did (0.670 -> 0.685 at 256 texels); the packing stays rigid at one scale,
    unmirrored and without overlap. Where it packs no better the layout is kept as chosen."""
    islands, nf, nv = [], 0, 0
    for k, cells in enumerate((8, 6, 4, 4)):
        islands.append(_disc(cells, 3.0 * k, nf, nv, k))
        nf, nv = nf + len(islands[-1].faces), nv + len(islands[-1].uv)
    comp = np.repeat(np.arange(4), [len(i.faces) for i in islands])
    got = choose_layout(islands, comp, UnwrapConfig(resolution=256, padding=2, pack_max_cuts=0))
    assert got.stats.get("brute_force") is True
    assert got.packing.utilization >= got.stats["utilization_before_brute"] + 0.01
    uv, faces, island = island_arrays(got.islands)
    px = got.packing.uv
    xyz = np.concatenate([isl.xyz for isl in got.islands])
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    ratio = np.linalg.norm(px[e[:, 0]] - px[e[:, 1]], axis=1) / np.linalg.norm(xyz[e[:, 0]] - xyz[e[:, 1]], axis=1)
    assert ratio == pytest.approx(np.full(len(ratio), ratio[0]), rel=1e-9)
    assert (signed_areas(px, faces) > 0).all()
    assert verify_packing(px, faces, island, 256)[0] == 0
    square = choose_layout(islands[:1], comp[:len(islands[0].faces)], UnwrapConfig(resolution=256, padding=2, pack_max_cuts=0))
    assert "brute_force" not in square.stats  # one disc: nothing to place better
    assert square.packing.utilization == pytest.approx(square.stats["utilization_before_brute"])


def _l_island(nx: int, ny: int, label: int) -> Island:
    """An L: an nx-by-ny grid of 0.25 cells less its corner beyond 40 % of each side."""
    g = _grid_island(nx, ny, 0.25)
    c = g.uv[g.faces].mean(1)
    f = g.faces[~((c[:, 0] > nx * 0.1) & (c[:, 1] > ny * 0.1))]
    vid, inv = np.unique(f, return_inverse=True)
    uv = g.uv[vid]
    return Island(inv.reshape(-1, 3), uv, np.column_stack([uv, np.zeros(len(uv))]), np.arange(len(f)),
                  np.arange(len(uv)), label)


def test_a_layout_whose_plan_clears_the_floor_but_whose_packing_does_not_is_refused():
    """Four L islands turned to their minimum rectangles, xatlas free to turn them by quarter
    turns: its coarse plan turns (and so mirrors) some, and kept unmirrored they pack below
    the plan. With the floor between the two the packing did not pass it, so
    :func:`best_packed` returns None (its callers keep what they had); below the packing it
    returns that packing."""
    from texture.layout_packing import PACK_MODES, best_packed, outline_arrays, turned
    from texture.scale_search import plan_layouts

    mode = 2
    assert PACK_MODES[mode] == (True, {"rotate_charts_to_axis": False})

    islands = [_l_island(nx, ny, k) for k, (nx, ny) in enumerate(((10, 4), (7, 7), (5, 3), (3, 6)))]
    cfg = UnwrapConfig(resolution=256, padding=2)
    plan = plan_layouts([outline_arrays(turned(islands, PACK_MODES[mode]), {}, [])],
                        candidates=(PACK_MODES[mode][1],), resolution=256, padding=2)[0]
    packed = best_packed([islands], [mode], cfg, {})
    assert plan.utilization > packed.utilization + 0.01  # the case: unmirrored, it packs worse
    between = (plan.utilization + packed.utilization) / 2
    assert best_packed([islands], [mode], cfg, {}, between) is None
    again = best_packed([islands], [mode], cfg, {}, packed.utilization - 0.01)
    assert again.utilization == pytest.approx(packed.utilization)


def test_turned_islands_reuse_each_islands_rectangle_and_nothing_else(monkeypatch):
    """``turned`` with a cache finds each island's minimum-area rectangle once (the packing
    search turns the same islands in every layout), gives the same UVs as without it, and
    does not take a rectangle over to a new island whose UVs array reuses a freed one's id."""
    import texture.layout_packing as LP

    calls = []
    real = LP.min_rect_rotation
    monkeypatch.setattr(LP, "min_rect_rotation", lambda uv: calls.append(1) or real(uv))
    a, b = _grid_island(6, 2), _grid_island(3, 5)
    a.uv = a.uv @ np.array([[0.8, -0.6], [0.6, 0.8]]).T  # turned 37 degrees: its rectangle is not the axes
    mode = (True, {})
    cache: dict = {}
    first = LP.turned([a, b], mode, cache)
    again = LP.turned([b, a], mode, cache)
    assert len(calls) == 2
    plain = LP.turned([a, b], mode)
    for x, y in ((first[0], plain[0]), (first[1], plain[1]), (again[1], plain[0])):
        np.testing.assert_array_equal(x.uv, y.uv)
    np.testing.assert_allclose(np.ptp(first[0].uv, 0), [6.0, 2.0], atol=1e-12)
    c = _grid_island(2, 7)
    del a, first, again, plain
    LP.turned([c], mode, cache)  # a new array: its rectangle is found, whatever its id
    assert len(calls) == 5


def test_a_round_makes_the_shortest_cut_that_reaches_the_target_else_the_best_gain_per_length():
    """:func:`texture.unwrap_layout._chosen` on the halvings that paid in two measured rounds
    (utilisation as packed, length of the cut). The cup with a handle (target 0.6): cuts of
    3.29, 1.42 and 1.40 packing 0.623, 0.605 and 0.596: the 1.42 cut, the shortest that
    reaches the target, not the 3.29 that packs most. The sphere's first round (from 0.357):
    2.70 packing 0.506 and 1.82 packing 0.504, neither at the target: the 1.82 cut, which buys
    0.081 per unit of length where the other buys 0.055. With no shorter cut the most
    utilisation per length is still the most utilisation."""
    from types import SimpleNamespace

    from texture.unwrap_layout import _chosen

    cfg = UnwrapConfig()
    assert cfg.pack_target == 0.6

    def opts(*pairs):
        return [(SimpleNamespace(utilization=u), cut, k) for k, (u, cut) in enumerate(pairs)]

    assert _chosen(opts((0.623, 3.29), (0.605, 1.42), (0.596, 1.40)), cfg, 0.487)[2] == 1
    assert _chosen(opts((0.506, 2.70), (0.504, 1.82)), cfg, 0.357)[2] == 1
    assert _chosen(opts((0.506, 2.70), (0.504, 2.70)), cfg, 0.357)[2] == 0
    # equal cuts reaching the target (one halving in two packing modes): the better packed
    assert _chosen(opts((0.61, 1.0), (0.65, 1.0), (0.70, 1.5)), cfg, 0.5)[2] == 1


def _block_with_strip(block: int = 12, strip_w: int = 2, strip_l: int = 18, cell: float = 0.37) -> Island:
    """A flat ``block``-by-``block`` grid of ``cell``-sized cells with a strip ``strip_w``
    cells wide and ``strip_l`` cells long sticking out of the middle of one side (UV = xy)."""
    mask = np.zeros((block, block + strip_l), bool)
    mask[:, :block] = True
    mid = block // 2 - strip_w // 2
    mask[mid:mid + strip_w, block:] = True
    g = _grid_island(mask.shape[1], mask.shape[0], cell)
    faces = g.faces[np.tile(mask.ravel(), 2)]
    vid, inv = np.unique(faces, return_inverse=True)
    faces = inv.reshape(-1, 3)
    return Island(faces, g.uv[vid], g.xyz[vid], np.arange(len(faces)), np.arange(len(vid)), 0)


def test_a_strip_sticking_out_of_a_block_is_cut_off_at_its_neck():
    """The protrusion found by the footprint's opening is the strip, cut where it meets the
    block: the cut's 3D length is the strip's width (2 cells of 0.37) and the piece cut off
    holds the strip's area, within a row of cells; the pieces keep the island's UVs. A plain
    block (a square: the opening rounds only its corners) has no protrusion."""
    from texture.regions import face_adjacency
    from texture.spikes import spike_cuts

    isl = _block_with_strip()
    got = spike_cuts(isl, face_adjacency(isl.xyz, isl.faces))
    assert got, "the strip is a protrusion"
    (body, strip), length, what = min(got, key=lambda g: abs(g[1] - 2 * 0.37))
    assert length == pytest.approx(2 * 0.37, rel=1e-9)
    strip_area, total = 2 * 18 * 0.37 ** 2, (12 * 12 + 2 * 18) * 0.37 ** 2
    assert abs(what["share"] * total - strip_area) <= 2 * 0.37 ** 2 + 1e-9
    assert len(body.faces) + len(strip.faces) == len(isl.faces)
    for piece in (body, strip):  # each piece's UVs are the island's at its vertices
        np.testing.assert_array_equal(piece.uv, isl.uv[piece.work_vertex])
    block = _grid_island(12, 12, 0.37)
    assert spike_cuts(block, face_adjacency(block.xyz, block.faces)) == []


def test_the_packing_search_cuts_a_protrusion_off_where_it_packs_better():
    """A 16-cell block with a strip 2 x 12 cells (8.6 % of the area: past every halving's
    positions, 15-85 % along the axis) packs 0.36 whole; the search cuts the strip off at its
    neck (as long as the strip is wide, where the block's halvings cut 16 cells across) and
    packs above the target, with one scale and no overlap."""
    isl = _block_with_strip(block=16, strip_l=12)
    comp = np.zeros(len(isl.faces), np.int64)
    cfg = UnwrapConfig(resolution=512, padding=4)
    got = choose_layout([isl], comp, cfg)
    assert got.stats["utilization_uncut"] < 0.6 <= got.packing.utilization
    spikes = [h for h in got.stats["halvings"] if h["at"] == "spike"]
    assert [h["at"] for h in got.stats["halvings"]] == ["spike"]
    assert spikes[0]["cut_length"] == pytest.approx(2 * 0.37, rel=1e-9)
    _, faces, island = island_arrays(got.islands)
    assert verify_packing(got.packing.uv, faces, island, 512)[0] == 0


def test_rounds_that_end_below_the_target_with_protrusions_cut_are_run_again_without():
    """Where the rounds cut a protrusion off and still end below the target (0.95 here), the
    rounds without such cuts run too and the better layout is kept: what is delivered packs
    at least as well as either. Where they reach it (0.6), they are not run."""
    isl = _block_with_strip(block=16, strip_l=12)
    comp = np.zeros(len(isl.faces), np.int64)
    got = choose_layout([isl], comp, UnwrapConfig(resolution=512, padding=4, pack_target=0.95))
    st = got.stats
    assert "with_spikes" in st and "without_spikes" in st
    assert got.packing.utilization == max(st["with_spikes"], st["without_spikes"])
    reached = choose_layout([isl], comp, UnwrapConfig(resolution=512, padding=4))
    assert "without_spikes" not in reached.stats


def test_each_halving_of_an_island_is_cut_once_in_a_search(monkeypatch):
    """The packing search cuts each halving of an island once: later rounds, the quarter-turned
    judgements and the pairs take it from the search's cache (the same cut: it depends on the
    island only), and choose the comb's three halvings as before. A round's halvings asked
    for again are the same candidates with no new cut; an island with equal but new arrays
    is cut anew."""
    import texture.unwrap_layout as UL

    calls = []  # the islands themselves are kept, so no id below is reused by another array
    real = UL.halve_across

    def spy(isl, along, cuts, adj):
        calls.append((isl, along, tuple(np.round(cuts, 9))))
        return real(isl, along, cuts, adj)

    monkeypatch.setattr(UL, "halve_across", spy)
    (comb, small), comp = _comb_and_small()
    cfg = UnwrapConfig(resolution=512, padding=4)
    got = choose_layout([comb, small], comp, cfg)
    assert len(got.stats["halvings"]) == 3 and got.packing.utilization >= 0.6 and len(got.islands) == 5
    keys = [(id(isl.faces), id(isl.uv), along, cuts) for isl, along, cuts in calls]
    assert len(keys) > 12 and len(set(keys)) == len(keys)
    cache: dict = {}
    first = UL._halvings([comb, small], comp, cfg, False, cache)
    n = len(calls)
    again = UL._halvings([comb, small], comp, cfg, False, cache)
    assert len(calls) == n and len(again) == len(first) >= 6
    for (a, da), (b, db) in zip(first, again):
        assert da == db and len(a) == len(b) and all(x is y for x, y in zip(a, b))
    fresh = Island(comb.faces.copy(), comb.uv.copy(), comb.xyz, comb.work_faces, comb.work_vertex, comb.label)
    UL._halvings([fresh, small], comp, cfg, False, cache)
    assert len(calls) > n
