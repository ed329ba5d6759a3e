"""One UV-metrics harness for every triangle mesh with UVs (our atlas, xatlas, user meshes).

``measure(mesh)`` returns :class:`UVMetrics`: per-face arrays and a JSON-friendly
``summary``. Positions are first normalised to the unit ball (DESIGN: centre = bbox
centre, max radius 1) and UVs rescaled globally so total UV area = total 3D area
(see ``distortion_faces.equal_area_uv_scale``); every number is then scale-free.

Summary keys (example values in docs/texture.md):

``charts``             connected UV islands (edge-connected in UV) that cover some UV
                       area. ``point_charts``: those that cover none (a degenerate input
                       face parked on one UV point, :mod:`texture.unwrap`): they carry no
                       texture, so they are not charts a user sees or packs.
``seam_length``        3D length of cut edges / sqrt(surface area). A cut edge is a UV
                       boundary edge that is not on the surface's open boundary; its two
                       sides are counted once (0.5 each).
``distortion_*``       DESIGN's metric / conformal / area distortions, UV-area weighted;
``distortion_*_3d``    the same weighted by 3D area.
``flipped_faces``      faces whose UV orientation disagrees with their island's majority
                       (majority by UV area); ``flipped_area_percent`` their 3D area.
``mirrored_area_percent`` 3D area (percent) of faces whose UV triangle runs clockwise seen
                       from the face's front (the side its winding, and so every viewer's
                       normal, faces): there the texture reads mirrored, text backwards.
                       ``mirrored_islands``: islands whose majority (by UV area) is mirrored.
``folded_faces``       faces whose 3D normal disagrees (negative dot product) with the
                       reference normal, against their island's majority (by 3D area).
                       Reference = the reference surface's (vertex-interpolated) normal at
                       the closest point when ``reference`` is given, else the island's
                       own area-weighted vertex normals. With a reference, such a face is
                       *undecided*, not folded, when a reference facet within ``FOLD_TOL``
                       (1 % of the diameter) beyond its closest distance faces its way:
                       where the reference has both orientations that close (the two sides
                       of a thin part, touching parts, the far side of a sharp crease) the
                       orientation is not determined at the fit's resolution. A facet faces
                       a way by its vertex normals' side or by its own winding: on a
                       double-sided reference (each face beside a copy wound the other way)
                       the vertex normals cancel, and only the windings show both ways.
``orientation_undecided_area_percent`` the 3D area of those faces.
``uv_overlap_percent`` texels of ``resolution^2`` covered by >= 2 faces (a face repeated
                       exactly, the same 3D points and UVs, counts once), percent of
                       covered texels (UV bounding box mapped to the square if UVs leave
                       [0,1]^2).
``utilization``        covered fraction of [0,1]^2 (texel centres, ``resolution^2``).
``texel_density_cv``   3D-area weighted coefficient of variation of
                       ``sqrt(uv area / 3D area)``; ``texel_density_p90_p10`` its 90/10
                       percentile ratio (1 = the same texel size everywhere).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mnacore import distortion as D

#: default texel grid for overlap and utilisation.
from mnacore.frame import Normalization, unit_ball_normalization
from mnacore.tolerances import SURFACE_TOL
from mnacore.triangles import face_normals
from mnacore.uvmesh import UVMesh, make_uv_mesh, weld_ids

from . import islands as _islands
from .distortion_faces import FaceGeometry, equal_area_uv_scale, face_geometry, per_face_from_geometry
from .geometry import MeshProjector, distance_to_segments
from .raster import coverage_count

RESOLUTION = 1024
#: distance (unit-ball frame, 1 % of the diameter) within which an island border counts
#: as lying on the reference surface's open boundary rather than being a seam.
BOUNDARY_TOL = SURFACE_TOL
#: the same 1 % of the diameter: a face whose normal opposes the reference is still not
#: folded if a reference facet within this beyond the closest point faces its way.
FOLD_TOL = SURFACE_TOL


def per_face_distortions(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> dict[str, np.ndarray]:
    """Per-face DESIGN distortions of the map UV -> 3D; keys ``metric``, ``conformal``, ``area``, each (F,).

    Args:
        vertices: (V, 3) positions (any frame: they are normalised to the unit ball).
        faces: (F, 3) int vertex indices.
        uv: (V, 2) per-vertex UVs (any scale: rescaled to equal total area).

    Each array is a per-face decomposition of the UV-area weighted aggregate, i.e.
    ``sum(w * out[k]) / sum(w) == distortion_k`` with ``w = |UV area|``:

    - ``metric``: ``s tr(g_f + eps I) + tr((g_f + eps I)^-1) / s - 4`` at the optimal
      global ``s = sqrt(E[tr g^-1] / E[tr g])``;
    - ``conformal``: ``tr g_f / sqrt(det g_f) - 2`` (MIPS);
    - ``area``: ``t A_f + 1 / (t A_f) - 2``, ``A_f = sqrt(det g_f)``, ``t = sqrt(E[1/A] / E[A])``.

    All are 0 for an isometry up to one global scale. Faces with zero UV area get NaN.
    """
    mesh = make_uv_mesh(vertices, faces, uv)
    norm = unit_ball_normalization(mesh.vertices[np.unique(mesh.faces)])
    return per_face_from_geometry(face_geometry(norm.apply(mesh.vertices), mesh.faces, mesh.uv))


def uv_islands(faces: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(F,) UV island id per face (edge-connected in UV), ids ``0..n-1``; see ``islands.uv_islands``."""
    return _islands.uv_islands(faces, uv)


@dataclass
class UVMetrics:
    """Harness output: per-face arrays (F,) and the aggregated, JSON-friendly ``summary``."""

    metric: np.ndarray
    conformal: np.ndarray
    area: np.ndarray
    island: np.ndarray
    flipped: np.ndarray
    folded: np.ndarray
    uv_area: np.ndarray
    area_3d: np.ndarray
    texel_density: np.ndarray
    summary: dict = field(default_factory=dict)


def _aggregates(geom: FaceGeometry) -> dict:
    v = geom.valid
    g = D.metric_tensor(geom.jac[v] * equal_area_uv_scale(geom))
    out = {}
    for suffix, w in (("", np.abs(geom.uv_area[v])), ("_3d", geom.area_3d[v])):
        d = D.all_distortions(g, weights=w) if v.any() else D.Distortions(np.nan, np.nan, np.nan)
        out[f"distortion_metric{suffix}"] = d.metric
        out[f"distortion_conformal{suffix}"] = d.conformal
        out[f"distortion_area{suffix}"] = d.area
    return out


def _majority_disagrees(sign: np.ndarray, weight: np.ndarray, island: np.ndarray) -> np.ndarray:
    """(F,) faces whose ``sign`` (+-1, 0 = undecided) opposes their island's weighted majority."""
    vote = np.bincount(island, weights=sign * weight, minlength=island.max() + 1)
    major = np.sign(vote)[island]
    return (sign != 0) & (major != 0) & (sign != major)


def _mirrored(geom: FaceGeometry, island: np.ndarray) -> tuple[np.ndarray, int]:
    """((F,) faces with clockwise UVs seen from their front, number of mostly-mirrored islands)."""
    mirrored = geom.valid & (geom.uv_area < 0)
    vote = np.bincount(island, weights=np.where(geom.valid, geom.uv_area, 0.0), minlength=island.max() + 1)
    return mirrored, int((vote < 0).sum())


def _flipped(geom: FaceGeometry, island: np.ndarray) -> np.ndarray:
    sign = np.where(geom.valid, np.sign(geom.uv_area), 0.0)
    return _majority_disagrees(sign, np.abs(geom.uv_area), island)


def _smoothed_normals(mesh: UVMesh, geom: FaceGeometry, island: np.ndarray, weld: np.ndarray) -> np.ndarray:
    """(F, 3) per face: area-weighted normal around its corners, within its island."""
    n_pts = int(weld.max()) + 1
    key = island[:, None] * n_pts + weld[mesh.faces]  # (F, 3) corner -> (island, point)
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    acc = np.zeros((len(uniq), 3))
    np.add.at(acc, inv, np.repeat(geom.normal * geom.area_3d[:, None], 3, 0))
    return acc[inv].reshape(-1, 3, 3).sum(1)


def facet_normals(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(F, 3) unit normals of the planes of ``faces``, each turned to the side of the mean
    of its vertex ``normals`` (the reference's own idea of outside, whatever its winding)."""
    n = face_normals(vertices, faces, unit=False)
    n *= np.where((n * normals[faces].sum(1)).sum(1) < 0, -1.0, 1.0)[:, None]
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _folded(mesh, geom, island, weld, reference: MeshProjector | None) -> tuple[np.ndarray, np.ndarray]:
    """(folded, undecided) per face; see the module docstring."""
    undecided = np.zeros(len(geom.area_3d), bool)
    if reference is not None:
        centroid = mesh.vertices[mesh.faces].mean(1)
        proj = reference.project(centroid)
        # smooth (vertex-normal) reference: facet normals of a coarse reference are noisy
        ref_n = (proj.bary[:, :, None] * reference.normals[reference.faces[proj.face]]).sum(1)
    else:
        ref_n = _smoothed_normals(mesh, geom, island, weld)
    dot = (geom.normal * ref_n).sum(1)
    sign = np.where(geom.area_3d > 0, np.sign(dot), 0.0)
    against = _majority_disagrees(sign, geom.area_3d, island)
    if reference is not None and against.any():
        # undecided: a reference facet within FOLD_TOL beyond the closest point faces the
        # face's way (a thin part's other side, touching parts, the far side of a crease),
        # turned to its vertex normals' side (the reference's idea of outside, whatever its
        # winding) or as wound: on a double-sided reference (each face beside a copy wound
        # the other way) the vertex normals cancel, and only the windings face both ways
        idx = np.flatnonzero(against)
        facet = facet_normals(reference.vertices, reference.faces, reference.normals)
        wound = face_normals(reference.vertices, reference.faces)

        def supports(i, f):
            way = -sign[idx[i]]
            return ((np.sign((facet[f] * geom.normal[idx[i]]).sum(1)) == way)
                    | (np.sign((wound[f] * geom.normal[idx[i]]).sum(1)) == way))

        i, _, _ = reference.faces_within(centroid[idx], proj.distance[idx] + FOLD_TOL, where=supports)
        undecided[idx[np.unique(i)]] = True
    return against & ~undecided, undecided


def distinct_faces(faces: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Indices of the ``faces`` but exact repeats: a face on the same 3D points with the same
    UVs at them (``point``: :func:`texture.islands.uv_point_ids` with the weld) as an earlier
    face (an input that wrote a face twice, unwrapped with one UV triangle for both) is the
    same piece of surface on the same texels, so it is counted once where faces are counted
    against each other (seams, overlap)."""
    pid = np.sort(point[faces], 1)
    order = np.lexsort(pid.T[::-1])  # stable: of equal faces the earliest comes first
    ranked = pid[order]
    first = np.r_[True, (ranked[1:] != ranked[:-1]).any(1)]
    return np.sort(order[first])


def _seam_length(mesh: UVMesh, weld: np.ndarray, point: np.ndarray, surface_boundary: np.ndarray | None,
                 distinct: np.ndarray) -> float:
    """0.5 * sum of 3D lengths of UV-boundary half-edges not on the surface's open boundary
    (over the ``distinct`` faces, :func:`distinct_faces`; ``point``: each vertex's UV point)."""
    faces = mesh.faces[distinct]
    he = _islands.half_edges(faces)
    uv_keys = _islands.edge_keys(point, faces)
    uv_open = _islands.edge_use_counts(uv_keys) == 1
    open3d = _islands.edge_use_counts(_islands.edge_keys(weld, faces)) == 1
    p = mesh.vertices[he]
    length = np.linalg.norm(p[:, 1] - p[:, 0], axis=1)
    on_surface_boundary = open3d.copy()
    if surface_boundary is not None:
        # an open 3D edge is a real boundary only if it lies on the reference's boundary
        near = distance_to_segments(p[open3d].mean(1), surface_boundary) < BOUNDARY_TOL
        on_surface_boundary[open3d] = near
    return 0.5 * float(length[uv_open & ~on_surface_boundary].sum())


def _texture_space(uv: np.ndarray) -> tuple[np.ndarray, bool]:
    """UVs as used for rasterising: unchanged if inside [0,1]^2, else the bbox mapped to it."""
    inside = bool(uv.min() >= -1e-9 and uv.max() <= 1 + 1e-9)
    if inside:
        return uv, True
    lo = uv.min(0)
    return (uv - lo) / max(float((uv.max(0) - lo).max()), 1e-300), False


def _texel_density(geom: FaceGeometry) -> tuple[np.ndarray, float, float]:
    rho = np.sqrt(np.abs(geom.uv_area) / np.maximum(geom.area_3d, 1e-300))
    rho[geom.area_3d <= 0] = np.nan
    ok = np.isfinite(rho) & geom.valid
    if not ok.any():  # every UV triangle degenerate: no density to speak of
        return rho, float("nan"), float("nan")
    w = geom.area_3d[ok]
    mean = float((rho[ok] * w).sum() / w.sum())
    std = float(np.sqrt(((rho[ok] - mean) ** 2 * w).sum() / w.sum()))
    p10, p90 = np.percentile(rho[ok], [10, 90])
    return rho, std / mean, float(p90 / p10) if p10 > 0 else float("inf")


def measure(mesh: UVMesh, *, reference=None, normalization: Normalization | None = None,
            resolution: int = RESOLUTION, reference_is_closed: bool = False) -> UVMetrics:
    """All harness metrics of ``mesh`` (see module docstring for the definitions).

    Args:
        mesh: the UV mesh, in any frame (usually the input's).
        reference: optional ``trimesh.Trimesh`` of the true surface in the *same* frame:
            gives the normals for folded faces and the open boundary for seams.
        normalization: unit-ball frame to use; default = the mesh's own bounding box.
        resolution: texel grid (``resolution^2``) for overlap and utilisation.
        reference_is_closed: without ``reference``, count every open border of ``mesh``
            as a seam (for a patchwork of separate charts of a closed surface).
    """
    norm = normalization or unit_ball_normalization(mesh.vertices[np.unique(mesh.faces)])
    m = mesh.transformed(norm)
    geom = face_geometry(m.vertices, m.faces, m.uv)
    weld = weld_ids(m.vertices)
    island = _islands.uv_islands(m.faces, m.uv, weld)
    per_face = per_face_from_geometry(geom)
    projector, boundary = None, None
    if reference is not None:
        rv = norm.apply(reference.vertices)
        projector = MeshProjector(rv, reference.faces)
        projector.normals = np.asarray(reference.vertex_normals, np.float64)
        from .geometry import boundary_segments

        boundary = boundary_segments(rv, np.asarray(reference.faces))
    elif reference_is_closed:
        boundary = np.zeros((0, 2, 3))
    flipped = _flipped(geom, island)
    mirrored, mirrored_islands = _mirrored(geom, island)
    folded, undecided = _folded(m, geom, island, weld, projector)
    total_area = float(geom.area_3d.sum())
    tex_uv, inside = _texture_space(m.uv)
    point = _islands.uv_point_ids(m.uv, weld)
    distinct = distinct_faces(m.faces, point)
    count = coverage_count(tex_uv[m.faces[distinct]], resolution, resolution)
    covered = int((count > 0).sum())
    rho, cv, p9010 = _texel_density(geom)
    charts = len(np.unique(island[np.abs(geom.uv_area) > 0]))  # islands that cover some UV area
    summary = {
        "faces": m.n_faces,
        "vertices": int(len(m.vertices)),
        "charts": charts,
        "point_charts": int(island.max() + 1) - charts,
        "seam_length": _seam_length(m, weld, point, boundary, distinct) / np.sqrt(total_area),
        **_aggregates(geom),
        "flipped_faces": int(flipped.sum()),
        "flipped_area_percent": 100.0 * float(geom.area_3d[flipped].sum()) / total_area,
        "mirrored_area_percent": 100.0 * float(geom.area_3d[mirrored].sum()) / total_area,
        "mirrored_islands": mirrored_islands,
        "folded_faces": int(folded.sum()),
        "folded_area_percent": 100.0 * float(geom.area_3d[folded].sum()) / total_area,
        "orientation_undecided_area_percent": 100.0 * float(geom.area_3d[undecided].sum()) / total_area,
        "uv_overlap_percent": 100.0 * int((count > 1).sum()) / max(covered, 1),
        "utilization": covered / float(resolution * resolution) if inside else float("nan"),
        "uv_inside_unit_square": inside,
        "texel_density_cv": cv,
        "texel_density_p90_p10": p9010,
        "degenerate_uv_faces": int((~geom.valid).sum()),
        "surface_area": total_area,
        "resolution": int(resolution),
    }
    summary = {k: (float(v) if isinstance(v, (np.floating,)) else v) for k, v in summary.items()}
    return UVMetrics(per_face["metric"], per_face["conformal"], per_face["area"], island,
                     flipped, folded, np.abs(geom.uv_area), geom.area_3d, rho, summary)
