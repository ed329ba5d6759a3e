"""Faces that repeat points: the rim of a double-sided open surface (its front and back stay
joined, and no two working edges join the same two working vertices:
:func:`texture.meshprep.fold_cuts`), and faces written twice (:func:`texture.meshprep.copied_faces`)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh
from test_unwrap import FAST, chart_from_function, check_faithful, cylinder, cylinder_chart

from mnacore.frame import unit_ball_normalization
from texture.harness import measure
from texture.meshprep import copied_faces, doubled_edges, prepare_mesh
from texture.unwrap import UnwrapConfig, unwrap_mesh

SCALE, OFFSET = 37.0, np.array([5.0, -120.0, 40.0])


def wavy(x, y):
    return 0.2 * np.sin(3 * x) * np.cos(2 * y)


def sheet(n: int):
    """A wavy n x n grid over [-1, 1]^2 (scaled, moved), each cell cut by the diagonal from
    its lower-left corner: two of its corners are a lone triangle, whose inner edge is a chord
    (both ends on the rim)."""
    xs = np.linspace(-1, 1, n + 1)
    X, Y = np.meshgrid(xs, xs)
    v = np.stack([X.ravel(), Y.ravel(), wavy(X, Y).ravel()], 1) * SCALE + OFFSET
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    f = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    return v, f


def working_edge_uses(prep) -> np.ndarray:
    wf = prep.work_faces
    he = np.stack([wf, np.roll(wf, -1, 1)], -1).reshape(-1, 2)
    n = int(wf.max()) + 1
    return np.unique(he.min(1) * n + he.max(1), return_counts=True)[1]


@pytest.mark.parametrize("n", [1, 12])
def test_a_double_sided_sheet_keeps_its_rim_and_no_doubled_chord(n):
    v, f = sheet(n)
    prep = prepare_mesh(v, np.vstack([f, f[:, ::-1]]))
    # every working edge has one face or two: no chord exists twice between the same ends
    assert working_edge_uses(prep).max() == 2 and len(doubled_edges(prep.work_faces)) == 0
    # the front and the back stay one surface, joined along the rim but where it was cut: at
    # one end of each of the two corner chords (n = 1: the card's one diagonal), the two folds
    # there, so that end has a front and a back copy
    chords = 1 if n == 1 else 2
    assert prep.stats["components"] == 1
    assert prep.stats["folds_cut"] == 2 * chords
    assert prep.stats["split_vertices"] == (n - 1) ** 2 + chords  # the inner points, front and back
    # the one-sided sheet has no folds to cut
    one = prepare_mesh(v, f)
    assert one.stats["folds_cut"] == 0 and working_edge_uses(one).max() == 2


def test_a_double_sided_sheet_unwraps_without_corner_specks():
    """One chart over the sheet: both sides take it, so the region is the whole double-sided
    sheet. With the chords doubled, the pinch split before the disk cut tore the corner
    triangles off (islands of one or two faces); now every island is a disk of the sheet,
    front and back are not mirrored, and the map is near isometric."""
    v, f = sheet(24)
    both = np.vstack([f, f[:, ::-1]])
    charts = chart_from_function(lambda x, y: np.stack([x, y, wavy(x, y)], -1) * SCALE + OFFSET,
                                 unit_ball_normalization(v))
    mesh = trimesh.Trimesh(v, both, process=False)
    res = unwrap_mesh(v, both, charts, UnwrapConfig())
    check_faithful(mesh, res)
    sizes = np.bincount(res.island)
    assert sizes.min() >= 0.25 * len(f), sizes
    m = measure(res.mesh).summary
    assert m["flipped_faces"] == 0 and m["mirrored_area_percent"] == 0.0
    assert m["distortion_metric"] < 0.05


def test_copied_faces_are_faces_on_the_same_points_wound_the_same_way():
    wf = np.array([[0, 1, 2], [1, 2, 0], [2, 1, 0], [2, 3, 1], [0, 1, 2], [1, 3, 2]])
    # a rotation of the corners is the same face; the reversed one is a back, not a copy
    np.testing.assert_array_equal(copied_faces(wf), [-1, 0, -1, -1, 0, -1])


def test_faces_written_twice_share_their_originals_uvs():
    """An open cylinder with 40 of its faces written again (some with their corners rotated,
    one three times): the copies are left out of the working mesh, so the islands are the
    cylinder's, and each copy gets its original's UV triangle. Measured with each repeated
    face counted once (seams, overlap), it is the cylinder's own unwrap: the seam its length
    over the root of the larger area. On the old code each copy was an island of one face."""
    mesh = cylinder(radius=2.5, height=5.0)
    f = np.asarray(mesh.faces)
    rng = np.random.default_rng(1)
    pick = rng.choice(len(f), 40, replace=False)
    rep = np.array([np.roll(r, k) for r, k in zip(f[pick], np.arange(40) % 3)])
    both = np.vstack([f, rep, f[pick[:1]]])
    assert prepare_mesh(mesh.vertices, both).stats["copied_faces"] == 41
    cfg = replace(FAST, long_max_splits=0, pack_max_cuts=0)
    one = unwrap_mesh(mesh.vertices, f, cylinder_chart(mesh, 2.5, 5.0), cfg)
    two = unwrap_mesh(mesh.vertices, both, cylinder_chart(mesh, 2.5, 5.0), cfg)
    check_faithful(trimesh.Trimesh(mesh.vertices, both, process=False), two)
    assert two.stats["islands"] == one.stats["islands"] == 1
    orig = np.r_[pick, pick[:1]]
    uv = two.mesh.uv[two.mesh.faces]
    for k, o in enumerate(orig):  # the same UV at each copy corner as at its original's corner on that point
        c = len(f) + k
        at = {tuple(np.round(two.mesh.vertices[two.mesh.faces[o, j]], 9)): uv[o, j] for j in range(3)}
        for j in range(3):
            np.testing.assert_array_equal(uv[c, j], at[tuple(np.round(two.mesh.vertices[two.mesh.faces[c, j]], 9))])
    np.testing.assert_array_equal(two.island[len(f):], two.island[orig])
    m1, m2 = measure(one.mesh).summary, measure(two.mesh).summary
    area = lambda faces: trimesh.Trimesh(mesh.vertices, faces, process=False).area  # noqa: E731
    assert m2["seam_length"] == pytest.approx(m1["seam_length"] * np.sqrt(area(f) / area(both)), rel=1e-9)
    assert m2["charts"] == 1 and m2["uv_overlap_percent"] == 0.0 and m2["flipped_faces"] == 0
    assert m2["utilization"] == pytest.approx(m1["utilization"], rel=1e-9)
