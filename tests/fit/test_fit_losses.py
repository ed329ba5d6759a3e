"""Losses, the positive-label rule and Chamfer against naive loops; float64 gradcheck; c estimator."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mna import losses
from mna.inference import c_from_probabilities
from mna.metrics import chamfer_fscore
from mna.neighbors import nearest


def _f(x) -> float:
    """A loss term as a float (detached: no autograd warning)."""
    return float(torch.as_tensor(x).detach())


def test_positive_labels_match_naive_loop():
    rng = np.random.default_rng(0)
    samples = torch.from_numpy(rng.normal(size=(300, 3)))
    targets = torch.from_numpy(rng.normal(size=(120, 3)))
    nn = nearest(targets, samples)
    labels = losses.positive_labels(nn.index, len(samples))
    naive = np.zeros(len(samples), bool)
    for t in targets.numpy():
        naive[np.argmin(((samples.numpy() - t) ** 2).sum(1))] = True
    assert labels.numpy().tolist() == naive.tolist()
    assert 0 < labels.sum() <= len(targets)


def test_nearest_distances_match_naive_loop():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(70, 3))
    nn = nearest(torch.from_numpy(a), torch.from_numpy(b))
    naive = np.array([((b - p) ** 2).sum(1).min() for p in a])
    np.testing.assert_allclose(nn.dist2.numpy(), naive, rtol=1e-12)


def test_chamfer_and_fscore_match_naive_loop():
    rng = np.random.default_rng(2)
    x, y = rng.uniform(size=(80, 3)) * 0.2, rng.uniform(size=(60, 3)) * 0.2
    d_xy = np.array([np.sqrt(((y - p) ** 2).sum(1)).min() for p in x])
    d_yx = np.array([np.sqrt(((x - p) ** 2).sum(1)).min() for p in y])
    m = chamfer_fscore(x, y, threshold=0.03)
    assert m.chamfer == pytest.approx((d_xy**2).mean() + (d_yx**2).mean(), rel=1e-12)
    p, r = (d_xy < 0.03).mean() * 100, (d_yx < 0.03).mean() * 100
    assert (m.precision, m.recall) == pytest.approx((p, r))
    assert m.fscore == pytest.approx(2 * p * r / (p + r))


def test_identical_clouds_score_perfectly():
    x = np.random.default_rng(3).normal(size=(100, 3))
    m = chamfer_fscore(x, x)
    assert m.chamfer == 0.0 and m.fscore == 100.0


def test_reconstruction_loss_is_unidirectional_chamfer():
    rng = np.random.default_rng(4)
    pts = torch.from_numpy(rng.normal(size=(40, 3)))
    tgt = torch.from_numpy(rng.normal(size=(25, 3)))
    nn = nearest(tgt, pts)
    loss = losses.reconstruction_loss(tgt, pts[nn.index])
    naive = np.mean([((pts.numpy() - t) ** 2).sum(1).min() for t in tgt.numpy()])
    assert float(loss) == pytest.approx(naive, rel=1e-12)


def test_losses_gradcheck_float64():
    torch.manual_seed(0)
    tgt = torch.randn(6, 3, dtype=torch.float64)
    matched = torch.randn(6, 3, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda m: losses.reconstruction_loss(tgt, m), (matched,))
    labels = torch.tensor([1, 0, 1, 0, 0, 1], dtype=torch.bool)
    logits = torch.randn(6, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda x: losses.occupancy_loss(x, labels), (logits,))
    jac = (torch.randn(5, 3, 2, dtype=torch.float64)).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda j: losses.distortion_loss(j, 1e-4), (jac,))


def test_occupancy_loss_is_bce():
    logits = torch.tensor([0.0, 2.0, -1.0], dtype=torch.float64)
    labels = torch.tensor([True, False, True])
    p = torch.sigmoid(logits)
    expected = -(torch.log(p[0]) + torch.log(1 - p[1]) + torch.log(p[2])) / 3
    assert float(losses.occupancy_loss(logits, labels)) == pytest.approx(float(expected), rel=1e-12)


@pytest.mark.parametrize("c_true", [0.15, 0.3, 0.6])
def test_c_estimator_on_synthetic_pu_labels(c_true):
    # PU setting: 60 % of samples lie in the domain; a labelled-probability model outputs ~c
    # there and ~0 elsewhere. The top 40 % are all in-domain, so their median recovers c.
    g = torch.Generator().manual_seed(0)
    n = 20000
    inside = torch.rand(n, generator=g) < 0.6
    probs = torch.where(inside, c_true + 0.02 * torch.randn(n, generator=g), 0.01 * torch.rand(n, generator=g))
    c = c_from_probabilities(probs.view(2, 1, n // 2), eta=0.4)
    assert c.shape == (1,)
    # the top 40 % of a symmetric noise around c sit slightly above c: bound stated generously
    assert float(c) == pytest.approx(c_true, abs=0.02)


def test_c_estimator_is_per_shape():
    probs = torch.stack([torch.full((3, 100), 0.2), torch.full((3, 100), 0.7)], dim=1)  # (K=3, B=2, N)
    torch.testing.assert_close(c_from_probabilities(probs, 0.4), torch.tensor([0.2, 0.7]))


@pytest.mark.parametrize("atlasnet", [False, True])
def test_batched_objective_equals_per_shape_loop(atlasnet):
    """A batch of B shapes gives the mean of B single-shape objectives (latent-conditioned model)."""
    from mna import config as C
    from mna.model import NeuralAtlas
    from mna.objective import atlas_losses

    torch.manual_seed(0)
    cfg = C.tiny()
    cfg.model.latent = 4
    cfg.dist_samples = 8  # exercise the Jacobian subset path too
    cfg.ablation.atlasnet = atlasnet
    model = NeuralAtlas.from_config(cfg.model, cfg.ablation).double()
    K, B, N, T = 3, 2, 50, 40
    uv = torch.rand(K, B, N, 2, dtype=torch.float64) * 2 - 1
    targets = torch.randn(B, T, 3, dtype=torch.float64) * 0.5
    z = torch.randn(B, 4, dtype=torch.float64)
    batched = atlas_losses(model, uv, targets, cfg, z)
    singles = [atlas_losses(model, uv[:, b:b + 1], targets[b:b + 1], cfg, z[b:b + 1]) for b in range(B)]
    for name in ("rec", "occ", "dist", "total"):
        expected = sum(getattr(s, name) for s in singles) / B
        assert _f(getattr(batched, name)) == pytest.approx(_f(expected), rel=1e-10), name
    assert batched.positives == sum(s.positives for s in singles)


def _plane_jacobians(n: int, angle: float = 0.0) -> torch.Tensor:
    """``n`` copies of the Jacobian of a plane through the origin tilted by ``angle`` about x (normal (0, -sin, cos))."""
    j = torch.tensor([[1.0, 0.0], [0.0, np.cos(angle)], [0.0, np.sin(angle)]], dtype=torch.float64)
    return j.expand(n, 3, 2).clone()


def test_orientation_loss_closed_forms():
    up = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    jac = _plane_jacobians(8)
    one_group = torch.zeros(8, dtype=torch.long)
    agree = up.expand(8, 3)
    assert _f(losses.orientation_loss(jac, agree, one_group)) == 0.0
    # either handedness of a chart is fine: all normals reversed is still consistent
    assert _f(losses.orientation_loss(jac, -agree, one_group)) == 0.0
    # 2 of 8 reversed against a majority of 6: each contributes relu(1) = 1
    mixed = agree.clone()
    mixed[:2] = -up
    assert _f(losses.orientation_loss(jac, mixed, one_group)) == pytest.approx(2 / 8, abs=1e-15)
    # a reversed normal tilted by theta contributes cos(theta); the Jacobian's length does not matter
    theta = 0.3
    tilted = torch.tensor([0.0, np.sin(theta), -np.cos(theta)], dtype=torch.float64)
    normals = torch.cat([agree[:7], tilted[None]])
    assert _f(losses.orientation_loss(3.7 * jac, normals, one_group)) == pytest.approx(np.cos(theta) / 8, rel=1e-12)
    # the majority is per group: two charts of opposite handedness are both consistent
    groups = torch.tensor([0, 0, 0, 0, 1, 1, 1, 1])
    two = torch.cat([agree[:4], -agree[4:]])
    assert _f(losses.orientation_loss(jac, two, groups)) == 0.0
    two[7] = up  # one of chart 1's four normals disagrees with its majority (-up)
    assert _f(losses.orientation_loss(jac, two, groups)) == pytest.approx(1 / 8, abs=1e-15)


def test_orientation_loss_gradcheck():
    torch.manual_seed(3)
    jac = torch.randn(12, 3, 2, dtype=torch.float64, requires_grad=True)
    normals = torch.nn.functional.normalize(torch.randn(12, 3, dtype=torch.float64), dim=1)
    groups = torch.arange(12) % 2
    assert torch.autograd.gradcheck(lambda j: losses.orientation_loss(j, normals, groups), (jac,))


def _latent_atlas():
    """A ``tiny`` atlas in float64 with a 4-wide latent, and UV samples ``(3, 2, 50, 2)``."""
    from mna import config as C
    from mna.model import NeuralAtlas

    torch.manual_seed(0)
    cfg = C.tiny()
    cfg.model.latent = 4
    model = NeuralAtlas.from_config(cfg.model, cfg.ablation).double()
    return cfg, model, torch.rand(3, 2, 50, 2, dtype=torch.float64) * 2 - 1


def test_objective_orientation_term():
    """w_orient * L_orient enters the total; it is per-shape averaged like the other terms; no normals -> 0."""
    from mna.objective import atlas_losses

    cfg, model, uv = _latent_atlas()
    cfg.dist_samples = 8
    cfg.loss.w_orient = 0.5
    B, T = 2, 40
    targets = torch.randn(B, T, 3, dtype=torch.float64) * 0.5
    normals = torch.nn.functional.normalize(torch.randn(B, T, 3, dtype=torch.float64), dim=-1)
    z = torch.randn(B, 4, dtype=torch.float64)
    t = atlas_losses(model, uv, targets, cfg, z, normals)
    w = cfg.loss
    assert 0.0 < _f(t.orient) < 1.0
    assert _f(t.total) == pytest.approx(_f(w.w_rec * t.rec + w.w_occ * t.occ + w.w_dist * t.dist
                                                 + w.w_orient * t.orient), rel=1e-12)
    singles = [atlas_losses(model, uv[:, b:b + 1], targets[b:b + 1], cfg, z[b:b + 1], normals[b:b + 1])
               for b in range(B)]
    assert _f(t.orient) == pytest.approx(_f(sum(s.orient for s in singles)) / B, rel=1e-10)
    # reversing every normal keeps every chart consistent with itself: same loss
    assert _f(atlas_losses(model, uv, targets, cfg, z, -normals).orient) == pytest.approx(_f(t.orient), rel=1e-10)
    assert _f(atlas_losses(model, uv, targets, cfg, z).orient) == 0.0


def test_face_normals_of_a_scrambled_winding_face_the_way_of_their_neighbours():
    """L_orient asks each chart to face one way: the targets' normals must. A sphere with 30 %
    of its faces' winding reversed gives the normals of the sphere as wound (outward), face
    by face; a consistently wound mesh keeps trimesh's own normals."""
    from mna import shapes
    from mna.data import make_surface

    sphere = shapes.sphere(radius=1.0, subdivisions=3)
    faces = np.asarray(sphere.faces).copy()
    flip = np.random.default_rng(0).random(len(faces)) < 0.3
    faces[flip] = faces[flip][:, ::-1]
    want = make_surface(sphere.vertices, sphere.faces).face_normals
    got = make_surface(sphere.vertices, faces).face_normals
    np.testing.assert_allclose(got, want, atol=1e-12)
    centre = np.asarray(sphere.vertices)[sphere.faces].mean(1)
    assert ((want * centre).sum(1) > 0).all()  # outward, as the sphere is wound
    assert flip.sum() > 100


def test_objective_surface_term():
    """L_surf = mean over the first ``surface_samples`` samples of every chart (domain or not) of
    the squared distance to the nearest target (brute force), per shape, averaged over the batch;
    w_surface * L_surf enters the total; its gradient reaches chart points that are no positive."""
    from mna.objective import atlas_losses

    cfg, model, uv = _latent_atlas()
    cfg.surface_samples = 30
    cfg.loss.w_surface = 0.25
    K, B, T = 3, 2, 40
    # targets on a sphere of radius 3 around (5, 0, 0): every distance is far from 1, so a
    # squared-vs-plain or per-chart-vs-pooled slip shows
    targets = torch.nn.functional.normalize(torch.randn(B, T, 3, dtype=torch.float64), dim=-1) * 3
    targets = targets + torch.tensor([5.0, 0.0, 0.0], dtype=torch.float64)
    z = torch.randn(B, 4, dtype=torch.float64)
    t = atlas_losses(model, uv, targets, cfg, z)
    with torch.no_grad():
        x = model.chart(uv[:, :, :30], z).x
    brute = np.mean([torch.cdist(x[:, b].reshape(-1, 3), targets[b]).min(1).values.pow(2).mean().item()
                     for b in range(B)])
    assert brute > 4.0  # the charts start near the origin, the nearest targets about 2 away
    assert _f(t.surface) == pytest.approx(brute, rel=1e-10)
    w = cfg.loss
    assert _f(t.total) == pytest.approx(_f(w.w_rec * t.rec + w.w_occ * t.occ + w.w_dist * t.dist
                                                 + w.w_orient * t.orient + w.w_surface * t.surface), rel=1e-12)
    # with a single target, only one sample per shape is a positive: L_rec's gradient reaches
    # the chart's output bias of one chart at most; L_surf's reaches all three
    one = targets[:, :1]
    cfg.loss.w_rec = cfg.loss.w_occ = cfg.loss.w_dist = 0.0
    for weight, moved in ((0.0, 0), (1.0, K)):
        cfg.loss.w_surface = weight
        cfg.loss.w_rec = 1.0 - weight
        model.zero_grad()
        atlas_losses(model, uv[:, :1], one[:1], cfg, z[:1]).total.backward()
        grads = model.chart.out.b.grad.abs().sum(1)
        assert int((grads > 0).sum()) == (1 if weight == 0 else moved)
    cfg.loss.w_surface = 0.0
    assert _f(atlas_losses(model, uv, targets, cfg, z).surface) == 0.0


def test_exclusive_positives_closed_form():
    """Three charts sampled on the same grid of a 0.6-wide square: chart 0 in the plane z = 0
    (logit +1 for x < 0, -1 for x > 0), chart 1 a hair above it (z = 0.004 < NEAR_TOL,
    logit 0) and chart 2 well above (z = 0.05, logit 10). A target on the plane labels chart
    0's nearest sample where x < 0 and chart 1's where x > 0, though chart 0's samples are
    nearer everywhere; chart 2, the most sure but beyond NEAR_TOL, labels none. The distance
    returned is the nearest overall (chart 0's)."""
    from mna.objective import _exclusive_positives
    from mnacore.tolerances import NEAR_TOL

    assert 0.004 < NEAR_TOL < 0.05 - 0.03  # the grid's 0.02 spacing: in-plane offsets < 0.015
    g = torch.linspace(-0.3, 0.3, 31, dtype=torch.float64)
    plane = torch.stack(torch.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    N = len(plane)
    x = torch.stack([torch.cat([plane, torch.full((N, 1), h, dtype=torch.float64)], 1)
                     for h in (0.0, 0.004, 0.05)])
    logits = torch.stack([torch.where(plane[:, 0] < 0, 1.0, -1.0).double(), torch.zeros(N, dtype=torch.float64),
                          torch.full((N,), 10.0, dtype=torch.float64)])
    gen = torch.Generator().manual_seed(0)
    xy = (torch.rand(500, 2, generator=gen, dtype=torch.float64) - 0.5) * 0.5
    xy = xy[xy[:, 0].abs() > 0.02]  # clear of the grid column at x = 0, where the logit flips
    targets = torch.cat([xy, torch.zeros(len(xy), 1, dtype=torch.float64)], 1)
    idx, dist = _exclusive_positives(targets, x, logits)
    want_k = torch.where(xy[:, 0] < 0, 0, 1)
    assert torch.equal(idx // N, want_k)
    d_all = torch.cdist(targets, x.reshape(-1, 3))  # (T, K*N)
    d_want = d_all.reshape(-1, 3, N)[torch.arange(len(xy)), want_k]
    assert torch.equal(idx % N, d_want.argmin(1))
    torch.testing.assert_close(dist, d_all.min(1).values, rtol=1e-12, atol=1e-12)
    right = want_k == 1  # chart 1 took targets that chart 0 is nearer to
    assert right.sum() > 100 and (dist[right] < d_want[right].min(1).values).all()


def test_objective_exclusive_labels_match_brute_force():
    """With ``exclusive_labels`` L_occ is the BCE of every sample's logit against labels that
    mark, per target, the sample chosen by brute force (the nearest in the highest-logit chart
    among those within NEAR_TOL of the nearest sample), and L_rec pulls those samples. Chart 1
    is a copy of chart 0 with a higher label, so the two rules label different samples."""
    from mna.objective import atlas_losses
    from mnacore.tolerances import NEAR_TOL

    cfg, model, uv = _latent_atlas()
    with torch.no_grad():
        for name, p in model.chart.named_parameters():
            p[1] = p[0]
        model.label.out.b[1] += 3.0
    B, T, K, N = 2, 40, 3, 50
    z = torch.randn(B, 4, dtype=torch.float64)
    with torch.no_grad():
        x = model.chart(uv, z).x
        logit = model.label_logits(uv, x, z)
    targets = x[0, :, :T] + 0.003 * torch.randn(B, T, 3, dtype=torch.float64)
    labels = torch.zeros(K, B, N, dtype=torch.float64)
    rec = []
    for b in range(B):
        d = torch.cdist(targets[b], x[:, b].reshape(K * N, 3)).reshape(T, K, N)
        dk, ik = d.min(2)  # (T, K)
        ok = dk <= dk.min(1, keepdim=True).values + NEAR_TOL
        at = torch.stack([logit[j, b][ik[:, j]] for j in range(K)], 1)  # (T, K) logit at each nearest
        k = torch.where(ok, at, -torch.inf).argmax(1)
        n = ik[torch.arange(T), k]
        labels[k, b, n] = 1.0
        rec.append(((targets[b] - x[k, b, n]) ** 2).sum(1).mean())
    assert labels[1].sum() > 2 * labels[0].sum()  # the copy with the higher label takes most
    cfg.exclusive_labels = True
    t = atlas_losses(model, uv, targets, cfg, z)
    occ = losses.occupancy_loss(logit.reshape(-1), labels.reshape(-1))
    assert _f(t.occ) == pytest.approx(_f(occ), rel=1e-10)
    assert _f(t.rec) == pytest.approx(_f(torch.stack(rec).mean()), rel=1e-10)
    cfg.exclusive_labels = False
    assert _f(atlas_losses(model, uv, targets, cfg, z).occ) != pytest.approx(_f(occ), rel=1e-3)
