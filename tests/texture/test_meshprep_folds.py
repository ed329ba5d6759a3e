"""The rim of a double-sided open surface: its front and back stay joined, and no two working
edges join the same two working vertices (:func:`texture.meshprep.fold_cuts`)."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from test_unwrap import chart_from_function, check_faithful

from mnacore.frame import unit_ball_normalization
from texture.harness import measure
from texture.meshprep import doubled_edges, prepare_mesh
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
