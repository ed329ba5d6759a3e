"""texture.ears: faces hanging on their island by one edge move across the seam.

The closed form: a square grid (side 3, n = 8 cells, each cut by its (i,j)-(i+1,j+1)
diagonal) split into the cells below the diagonal and the rest has a staircase border of
2(n-1) cell edges. The lower-right triangle of each diagonal cell 1..n-2 is an ear (two
staircase edges, its diagonal inside); moving them turns the staircase into the diagonal
except its first and last step: (2 + (n-2) sqrt 2) cell edges.
"""
import numpy as np
import pytest

from mnacore.triangles import signed_areas
from texture.ears import move_ears
from texture.merge import interior_edges, island_seam
from texture.unwrap_islands import Island

N, SIDE = 8, 3.0
H = SIDE / N


def _grid():
    i, j = np.meshgrid(np.arange(N + 1), np.arange(N + 1), indexing="ij")
    xy = np.column_stack([i.ravel(), j.ravel()]) * H
    vid = lambda a, b: a * (N + 1) + b  # noqa: E731
    faces, cell = [], []
    for a in range(N):
        for b in range(N):
            faces += [[vid(a, b), vid(a + 1, b), vid(a + 1, b + 1)],   # lower right
                      [vid(a, b), vid(a + 1, b + 1), vid(a, b + 1)]]   # upper left
            cell += [(a, b), (a, b)]
    # a tilted plane in 3D (not z = 0): the UVs below are its isometric flattening
    rot = np.array([[1, 0, 0], [0, np.cos(0.4), np.sin(0.4)], [0, -np.sin(0.4), np.cos(0.4)]])
    xyz = np.column_stack([xy, np.zeros(len(xy))]) @ rot.T + [0.5, -1.0, 2.0]
    return xyz, xy, np.array(faces), np.array(cell)


def _island(xyz, uv, faces, sel, label):
    vid, inv = np.unique(faces[sel], return_inverse=True)
    return Island(inv.reshape(-1, 3), uv[vid].copy(), xyz[vid], sel, vid, label)


def _staircase(turn_b=0.0, shift_b=(0.0, 0.0)):
    xyz, xy, faces, cell = _grid()
    below = cell[:, 0] > cell[:, 1]
    a = _island(xyz, xy, faces, np.flatnonzero(below), 0)
    b = _island(xyz, xy, faces, np.flatnonzero(~below), 1)
    c, s = np.cos(turn_b), np.sin(turn_b)
    b.uv = b.uv @ np.array([[c, -s], [s, c]]).T + shift_b  # flattened on its own: any rigid motion
    return [a, b], faces


def _seam(islands, faces):
    interior = interior_edges(faces)
    return sum(island_seam(i, interior) for i in islands)


@pytest.mark.parametrize("turn", [0.0, 1.1])
def test_staircase_becomes_the_diagonal(turn):
    islands, faces = _staircase(turn, (4.0, -2.5))
    before = _seam(islands, faces)
    assert before == pytest.approx(2 * (N - 1) * H)
    out, st = move_ears(islands)
    after = _seam(out, faces)
    assert after == pytest.approx((2 + (N - 2) * np.sqrt(2)) * H, rel=1e-9)
    assert st["ears_moved"] == N - 2
    assert before - after == pytest.approx(st["seam_removed"], rel=1e-9)
    # every face kept once, with its own 3D corners; each island flip-free and a disk
    work = np.concatenate([i.work_faces for i in out])
    assert np.array_equal(np.sort(work), np.arange(len(faces)))
    for isl in out:
        assert np.allclose(isl.xyz[isl.faces], _grid()[0][faces[isl.work_faces]])
        assert (signed_areas(isl.uv, isl.faces) > 0).all()
        V, E, F = len(isl.uv), len(interior_edges(isl.faces).keys), len(isl.faces)
        boundary = 3 * F - 2 * E
        assert V - (E + boundary) + F == 1  # Euler characteristic of a disk
    # the moved faces take the other island's UVs: still an isometric, rigid copy
    moved = out[1]
    d_uv = np.linalg.norm(moved.uv[moved.faces[:, 0]] - moved.uv[moved.faces[:, 1]], axis=1)
    d_3d = np.linalg.norm(moved.xyz[moved.faces[:, 0]] - moved.xyz[moved.faces[:, 1]], axis=1)
    assert np.allclose(d_uv, d_3d)


@pytest.mark.parametrize("stretch", [1.2, 1.8])
def test_ears_keep_their_distortion_bound(stretch):
    """The island below the staircase stretched along u. A face moving into it takes its
    stretch: energy excess 0.13 at 1.2:1 (within MAX_ENERGY: faces enter it) and 1.55 at
    1.8:1 (none enters). Its own ears (upper-left triangles of the cells just below the
    diagonal, apex on the staircase) may leave it either way: they lose their stretch."""
    islands, faces = _staircase()
    islands[0].uv = islands[0].uv * [stretch, 1.0]
    before = set(islands[0].work_faces.tolist())
    out, st = move_ears(islands)
    entered = set(out[0].work_faces.tolist()) - before
    assert (len(entered) > 0) == (stretch < 1.5)
    assert st["ears_moved"] > 0
    assert _seam(islands, faces) - _seam(out, faces) == pytest.approx(st["seam_removed"], rel=1e-9)


def test_ear_whose_notch_is_taken_stays():
    """Another part of the receiving island reaching into a notch (here: a far vertex of the
    island below the staircase dragged into one) keeps that notch's ear where it is."""
    islands, faces = _staircase()
    a = islands[0]
    far = np.flatnonzero(np.all(np.isclose(a.uv, [7 * H, 1 * H]), axis=1))[0]
    a.uv[far] = [3.8 * H, 3.5 * H]  # inside the ear of cell (3, 3): corners (3,3), (4,3), (4,4)
    out, st = move_ears(islands)
    assert st["ears_moved"] == N - 3
    assert _seam(out, faces) == pytest.approx((2 + (N - 3) * np.sqrt(2) + 2) * H, rel=1e-9)


def test_no_ears_no_change():
    xyz, xy, faces, cell = _grid()
    lower = np.flatnonzero(cell[:, 0] < N // 2)  # a straight cut along grid lines: no ear
    islands = [_island(xyz, xy, faces, lower, 0),
               _island(xyz, xy, faces, np.setdiff1d(np.arange(len(faces)), lower), 1)]
    out, st = move_ears(islands)
    assert st["ears_moved"] == 0
    assert _seam(out, faces) == pytest.approx(SIDE)


def test_smooth_cut_is_move_ears_on_the_band():
    """A cut through one embedded island (the packing's halvings): only the faces around the
    cut take part, with the same result as moving ears between the whole halves."""
    from texture.ears import smooth_cut

    xyz, xy, faces, cell = _grid()
    whole = _island(xyz, xy, faces, np.arange(len(faces)), 0)
    lo = cell[:, 0] > cell[:, 1]
    new, removed = smooth_cut(whole, lo)
    assert removed == pytest.approx((N - 2) * (2 - np.sqrt(2)) * H, rel=1e-9)
    halves, _ = move_ears([_island(xyz, xy, faces, np.flatnonzero(lo), 0),
                           _island(xyz, xy, faces, np.flatnonzero(~lo), 1)])
    assert np.array_equal(np.flatnonzero(new), np.sort(halves[0].work_faces))
    assert (new != lo).sum() == N - 2
