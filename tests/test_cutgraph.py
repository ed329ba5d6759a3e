"""The short cut graph (texture.cutgraph): disks, and cut lengths against closed forms."""
import numpy as np
import pytest

from texture.cutgraph import short_cut_flags
from texture.flatten import cut_to_disk, euler_characteristic, is_disk


def _grid_faces(nu: int, nv: int, wrap_v: bool) -> np.ndarray:
    f = []
    for i in range(nu):
        for j in range(nv if wrap_v else nv - 1):
            a, b = i * nv + j, ((i + 1) % nu) * nv + j
            c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
            f += [[a, b, c], [a, c, d]]
    return np.array(f, np.int64)


def _cylinder(radius: float, height: float, nu: int, nv: int):
    t = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    z = np.linspace(0, height, nv)
    v = np.array([[radius * np.cos(a), radius * np.sin(a), h] for a in t for h in z])
    return v, _grid_faces(nu, nv, False)


def _torus(big: float, small: float, nu: int, nv: int):
    t = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    p = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    v = np.array([[(big + small * np.cos(b)) * np.cos(a), (big + small * np.cos(b)) * np.sin(a), small * np.sin(b)]
                  for a in t for b in p])
    return v, _grid_faces(nu, nv, True)


def _cut_length(v: np.ndarray, f: np.ndarray, flags: np.ndarray) -> float:
    """3D length of the flagged interior edges (each flagged from both of its faces)."""
    a, b = f, np.roll(f, -1, axis=1)
    key = np.minimum(a, b) * (int(f.max()) + 1) + np.maximum(a, b)
    _, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    interior = count[inv.reshape(-1, 3)] == 2
    return float(np.linalg.norm(v[a] - v[b], axis=2)[flags & interior].sum() / 2)


def _cut_is_disk(v, f, flags) -> bool:
    import igl

    return is_disk(np.asarray(igl.cut_mesh(np.asarray(v, np.float64), f, flags)[1]))


def test_open_cylinder_is_cut_along_its_height():
    # an annulus (two boundary loops, genus 0) needs one arc between its loops; the shortest is
    # a straight generator of the cylinder, as long as it is tall (libigl's cut: 8.44 here)
    v, f = _cylinder(2.5, 7.0, 64, 30)
    flags = short_cut_flags(v, f)
    assert _cut_is_disk(v, f, flags)
    assert _cut_length(v, f, flags) == pytest.approx(7.0, rel=1e-9)


def test_closed_torus_is_cut_along_two_short_loops():
    # genus 1, closed: two loops through the root. The shortest system: a meridian (a polygon of
    # 48 sides, radius r) and the inner equator (96 sides, radius R - r); the greedy loops from
    # any root are at most a meridian and a longitude of radius R + r (libigl's cut: 41.4 here)
    big, small = 3.0, 1.0
    v, f = _torus(big, small, 96, 48)
    flags = short_cut_flags(v, f)
    assert _cut_is_disk(v, f, flags)
    meridian = 2 * 48 * small * np.sin(np.pi / 48)
    inner = 2 * 96 * (big - small) * np.sin(np.pi / 96)
    length = _cut_length(v, f, flags)
    assert meridian + inner - 1e-9 <= length <= 2 * np.pi * small + 2 * np.pi * (big + small)
    disk = cut_to_disk(v, f)  # the product path: the same cut
    assert is_disk(disk.faces) and disk.cut_edges == int(flags.sum())


def test_holed_torus_and_three_holed_cylinder_become_disks():
    # a handle and a boundary loop (2 loops rooted at the boundary); three boundary loops (2 arcs)
    v, f = _torus(3.0, 1.0, 48, 24)
    holed = f[np.all(v[f][:, :, 0] < 3.5, axis=1) | (np.abs(v[f][:, :, 1]).max(axis=1) > 0.8)]
    assert euler_characteristic(holed) == -1  # genus 1, one hole
    flags = short_cut_flags(v, holed)
    assert _cut_is_disk(v, holed, flags)

    v, f = _cylinder(1.5, 4.0, 48, 24)
    centre = v[f].mean(axis=1)
    window = (np.abs(centre[:, 2] - 2.0) < 0.5) & (centre[:, 0] > 1.3)  # a third loop in the side
    side = f[~window]
    assert euler_characteristic(side) == -1
    flags = short_cut_flags(v, side)
    assert _cut_is_disk(v, side, flags)
    # the two shortest arcs joining the three loops run straight down and up from the window
    # to the rims: the height less the window's (a rim-to-rim arc would be 4.0 on its own)
    z = v[f[window]][:, :, 2]
    assert _cut_length(v, side, flags) == pytest.approx(4.0 - (z.max() - z.min()), rel=1e-9)


def test_disk_gets_no_cut():
    v, f = _cylinder(1.0, 1.0, 16, 5)
    flags = short_cut_flags(v, f[: len(f) // 2])  # half the side: a disk
    assert not flags.any()
