"""Ears: a face that hangs on its island by one edge moves across the seam to the island it pokes into.

Every island border is a path along the input's edges: chart borders, disk cuts, slits and
halvings all are, and an edge path zigzags. Where two consecutive border edges ``a-b`` and
``b-c`` are edges of one face, that face is an *ear*: it hangs on its island by its third
edge ``c-a`` only. The island across ``a-b`` and ``b-c`` already holds ``a``, ``b`` and
``c``, so the face can change sides using that island's own UVs: no vertex moves, the seam
loses ``a-b`` and ``b-c`` and gains ``c-a``, shorter by the triangle inequality.

A move is kept only where the face fits the other island's notch exactly, so nothing the
unwrap guarantees changes:

- the corner ``b`` has one copy in the face's island (the island stays a disk) and one gap
  in the other island's fan (two border edges), so the face closes that fan: its UV angle
  there plus the island's must make a full turn (no overlap), with the island's winding
  (no flip), and ``c-a`` is not an edge of that island yet;
- its distortion (``tr g + tr g^-1 - 4`` at the shared isometric scale) stays within
  :data:`MAX_ENERGY` or below what it was: one face barely moves the area-weighted metric,
  but the texture on it should not visibly smear.

Moves run in passes (no two moves of a pass touch the same face or vertex) until none is
left: a move can make a new ear on either side.
"""
from __future__ import annotations

import numpy as np

from mnacore.triangles import signed_areas

from .islands import half_edges
from .slits import face_energy

#: the most a moved face's energy excess may reach (unless it was higher where it was): a
#: 1.5:1 stretch (singular values 1.5 and 1) is 0.69, so this keeps a moved face's texels
#: within about that stretch
MAX_ENERGY = 0.7
#: passes over the islands (each moves every non-conflicting ear found)
MAX_PASSES = 12
#: tolerance on the full turn the angles at the closed corner must make (radians)
ANGLE_TOL = 1e-6


def _corner_angles(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) unsigned UV angle at each corner."""
    p = uv[faces]
    u = np.roll(p, -1, axis=1) - p
    v = np.roll(p, 1, axis=1) - p
    cross = np.abs(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])
    return np.arctan2(cross, (u * v).sum(-1))


def _inside(tri: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(P,) whether each point lies strictly inside the triangle ``tri (3, 2)`` (either winding)."""
    d = [(tri[(k + 1) % 3, 0] - tri[k, 0]) * (pts[:, 1] - tri[k, 1])
         - (tri[(k + 1) % 3, 1] - tri[k, 1]) * (pts[:, 0] - tri[k, 0]) for k in range(3)]
    d = np.stack(d, 1)
    return (d > 0).all(1) | (d < 0).all(1)


class _Atlas:
    """All islands as one split-vertex mesh: ``faces`` into nodes (``uv``, ``xyz``,
    ``work_vertex``), ``island`` and ``work_face`` per face."""

    def __init__(self, islands):
        self.offsets = np.cumsum([0] + [len(i.uv) for i in islands])
        self.uv = np.concatenate([i.uv for i in islands])
        self.xyz = np.concatenate([i.xyz for i in islands])
        self.work_vertex = np.concatenate([i.work_vertex for i in islands])
        self.faces = np.concatenate([i.faces + o for i, o in zip(islands, self.offsets)])
        self.island = np.repeat(np.arange(len(islands)), [len(i.faces) for i in islands])
        self.node_island = np.repeat(np.arange(len(islands)), [len(i.uv) for i in islands])
        self.work_face = np.concatenate([i.work_faces for i in islands])
        sign = [np.sign(signed_areas(i.uv, i.faces).sum()) for i in islands]
        self.sign = np.asarray(sign, float)

    def ears(self) -> tuple[np.ndarray, ...]:
        """Candidate ears: (face, apex corner, face across ``a-b``, that island's nodes a', b', c')."""
        F = self.faces
        he = half_edges(F)  # half-edge 3f+k runs from corner k to corner k+1
        wk = self.work_vertex[he]
        base = int(self.work_vertex.max()) + 1
        key = wk.min(1) * base + wk.max(1)
        order = np.argsort(key, kind="stable")
        same = np.flatnonzero(key[order][1:] == key[order][:-1])
        twin = np.full(len(he), -1)
        twin[order[same]], twin[order[same + 1]] = order[same + 1], order[same]
        has = twin >= 0
        shared = np.zeros(len(he), bool)
        shared[has] = (he[twin[has], 0] == he[has, 1]) & (he[twin[has], 1] == he[has, 0])
        seam = has & ~shared
        border = ~shared  # seams and the surface's own open border
        n = len(self.uv)
        uses = np.bincount(F.ravel(), minlength=n)
        out_deg = np.bincount(he[border, 0], minlength=n)
        in_deg = np.bincount(he[border, 1], minlength=n)
        s3, sh3 = seam.reshape(-1, 3), shared.reshape(-1, 3)
        found = []
        for k in range(3):  # apex at corner k: edges (k-1 -> k) and (k -> k+1) are seams
            km, kp = (k - 1) % 3, (k + 1) % 3
            f = np.flatnonzero(s3[:, km] & s3[:, k] & sh3[:, kp] & (uses[F[:, k]] == 1))
            t_ab, t_bc = twin[3 * f + km], twin[3 * f + k]  # (b' -> a') and (c' -> b') across
            g1, g2 = t_ab // 3, t_bc // 3
            b1, a1 = he[t_ab, 0], he[t_ab, 1]
            c1, b2 = he[t_bc, 0], he[t_bc, 1]
            ok = (self.island[g1] == self.island[g2]) & (b1 == b2) & (out_deg[b1] == 1) & (in_deg[b1] == 1)
            found.append((f[ok], np.full(ok.sum(), k), g1[ok], a1[ok], b1[ok], c1[ok]))
        f, k, g, a, b, c = (np.concatenate(x) for x in zip(*found))
        return f, k, g, a, b, c

    def fits(self, f, k, g, a, b, c) -> np.ndarray:
        """Which ears fit their new island's notch (see module docstring)."""
        isl = self.island[g]
        new = np.stack([a, b, c], 1)
        area = signed_areas(self.uv, new) * self.sign[isl]
        ang = _corner_angles(self.uv, self.faces)
        fan = np.bincount(self.faces.ravel(), weights=ang.ravel(), minlength=len(self.uv))
        turn = fan[b] + _corner_angles(self.uv, new)[:, 1]
        old = np.stack([self.faces[f, (k - 1) % 3], self.faces[f, k], self.faces[f, (k + 1) % 3]], 1)
        e_new, e_old = self._energy(new), self._energy(old)
        edges = half_edges(self.faces)
        base = len(self.uv)
        known = np.unique(np.minimum(edges[:, 0], edges[:, 1]) * base + np.maximum(edges[:, 0], edges[:, 1]))
        ca = np.isin(np.minimum(a, c) * base + np.maximum(a, c), known)
        ok = (area > 0) & (np.abs(turn - 2 * np.pi) < ANGLE_TOL) & ~ca & (e_new <= np.maximum(MAX_ENERGY, e_old))
        ok[ok] = self._empty(new[ok], isl[ok])
        return ok

    def _empty(self, tri: np.ndarray, isl: np.ndarray) -> np.ndarray:
        """Whether no other node of island ``isl`` lies in the node triangle ``tri``: another
        lobe of an island can reach into a notch that the fan around its corner leaves open."""
        from scipy.spatial import cKDTree

        out = np.ones(len(tri), bool)
        for i in np.unique(isl):
            rows = np.flatnonzero(isl == i)
            nodes = np.flatnonzero(self.node_island == i)
            tree = cKDTree(self.uv[nodes])
            p = self.uv[tri[rows]]  # (R, 3, 2)
            centre = p.mean(1)
            radius = np.linalg.norm(p - centre[:, None], axis=2).max(1)
            for r, near in zip(rows, tree.query_ball_point(centre, radius)):
                cand = np.setdiff1d(nodes[near], tri[r])
                out[r] = not _inside(self.uv[tri[r]], self.uv[cand]).any()
        return out

    def _energy(self, tri: np.ndarray) -> np.ndarray:
        """(T,) energy excess of the node triangles ``tri (T, 3)`` (:func:`texture.slits.face_energy`)."""
        flat = np.arange(3 * len(tri)).reshape(-1, 3)
        return face_energy(self.xyz[tri].reshape(-1, 3), self.uv[tri].reshape(-1, 2), flat)

    def move(self, f, k, g, a, b, c) -> np.ndarray:
        """Move the ears that touch no face or node moved before in this pass; (moved,) mask."""
        F = self.faces
        busy_f, busy_n = set(), set()
        moved = np.zeros(len(f), bool)
        for i in range(len(f)):
            fi, gi = int(f[i]), int(g[i])
            nodes = {int(x) for x in F[fi]} | {int(a[i]), int(b[i]), int(c[i])}
            if fi in busy_f or gi in busy_f or nodes & busy_n:
                continue
            busy_f.update((fi, gi))
            busy_n.update(nodes)
            ki = int(k[i])
            F[fi, (ki - 1) % 3], F[fi, ki], F[fi, (ki + 1) % 3] = a[i], b[i], c[i]
            self.island[fi] = self.island[gi]
            moved[i] = True
        return moved

    def islands(self, old):
        """The islands rebuilt from the atlas (unused nodes dropped), fields of ``old`` kept."""
        from dataclasses import replace

        out = []
        for i, isl in enumerate(old):
            sel = np.flatnonzero(self.island == i)
            nodes, local = np.unique(self.faces[sel], return_inverse=True)
            out.append(replace(isl, faces=local.reshape(-1, 3).astype(np.int64), uv=self.uv[nodes],
                               xyz=self.xyz[nodes], work_faces=self.work_face[sel],
                               work_vertex=self.work_vertex[nodes]))
        return out


def move_ears(islands: list) -> tuple[list, dict]:
    """(islands with their ears moved, stats): see the module docstring. Islands are
    :class:`texture.unwrap_islands.Island`; their UVs at the shared isometric scale."""
    st = {"ears_moved": 0, "seam_removed": 0.0, "passes": 0}
    if len(islands) == 0:
        return islands, st
    atlas = _Atlas(islands)
    for _ in range(MAX_PASSES):
        f, k, g, a, b, c = atlas.ears()
        keep = atlas.fits(f, k, g, a, b, c)
        f, k, g, a, b, c = (x[keep] for x in (f, k, g, a, b, c))
        if len(f) == 0:
            break
        p = atlas.xyz
        gain = (np.linalg.norm(p[a] - p[b], axis=1) + np.linalg.norm(p[b] - p[c], axis=1)
                - np.linalg.norm(p[c] - p[a], axis=1))
        order = np.argsort(-gain, kind="stable")
        moved = atlas.move(*(x[order] for x in (f, k, g, a, b, c)))
        st["passes"] += 1
        st["ears_moved"] += int(moved.sum())
        st["seam_removed"] += float(gain[order][moved].sum())
    return atlas.islands(islands), st


def smooth_cut(isl, lo: np.ndarray) -> tuple[np.ndarray, float]:
    """(new ``lo``, seam removed): the ears of a cut through one embedded island moved across
    it, where ``lo (Fi,)`` marks the faces on one side. Both sides share the island's UVs,
    so every ear fits. Only the faces around the cut take part: every ear, and every vertex
    whose fan a move looks at, lies on the cut, and the cut only ever moves onto vertices
    already on it, so the band of faces touching it holds every move (at 1M faces the
    halvings of the packing search would otherwise rebuild whole islands)."""
    from dataclasses import replace

    faces = isl.faces
    on_lo = np.zeros(len(isl.uv), bool)
    on_hi = np.zeros(len(isl.uv), bool)
    on_lo[faces[lo].ravel()] = True
    on_hi[faces[~lo].ravel()] = True
    band = np.flatnonzero((on_lo & on_hi)[faces].any(1))
    # the island's own vertices and faces stand for the working mesh: copies along its
    # slits stay apart, as they are in its UVs
    local = replace(isl, work_faces=np.arange(len(faces)), work_vertex=np.arange(len(isl.uv)))
    sides = [band[lo[band]], band[~lo[band]]]
    if min(len(x) for x in sides) == 0:
        return lo, 0.0
    parts = [_part(local, sel) for sel in sides]
    out, st = move_ears(parts)
    new = lo.copy()
    new[out[0].work_faces] = True
    new[out[1].work_faces] = False
    return new, st["seam_removed"]


def _part(isl, sel: np.ndarray):
    """The faces ``sel`` of ``isl`` as an island of their own, vertices renumbered (as
    :mod:`texture.unwrap_islands`'s own sub-islands, which import this module)."""
    from dataclasses import replace

    vid, inv = np.unique(isl.faces[sel], return_inverse=True)
    return replace(isl, faces=inv.reshape(-1, 3).astype(np.int64), uv=isl.uv[vid], xyz=isl.xyz[vid],
                   work_faces=isl.work_faces[sel], work_vertex=isl.work_vertex[vid])
