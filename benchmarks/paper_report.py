"""The ``## paper`` section of RESULTS.md and the figure, from the rows paper_tables.py measured.

Every number printed comes from the rows; the verdicts come from :func:`mna.paper.claims`.
"""
from __future__ import annotations

from pathlib import Path

from mna import paper


def render_section(rows: list[dict], info: dict, hard: tuple[str, ...]) -> str:
    claims = paper.claims(rows, "conditional") + paper.claims(rows, "per-shape")
    topo_md, scores = paper.topology_table(rows)
    claims.append(paper.topology_claim(scores, hard))
    held = info["held_out"] * 6
    shapes = ", ".join(info["fit_shapes"])
    parts = [
        "## paper",
        "",
        f"`benchmarks/paper_tables.py --size {info['size']}` ({info['device']}, {info['machine']}, "
        f"{info['jobs']} runs at a time, {info['threads']} torch thread(s) each; load average at start "
        f"{info['load']:.1f}; {len(rows)} runs, {sum(r.get('seconds', 0.0) for r in rows) / 60:.0f} min summed over "
        "the runs). Budgets are epochs and steps, so the numbers do not depend on the load.",
        "",
        f"- **conditional** (the paper's setting): `mna train` on the procedural family (`mna.family`: "
        f"{info['per_topology']} members per topology, {held} held out; charts and label nets {info['width']} "
        f"wide, latent {info['latent']}, {info['points']} input/target points, {info['uv']} UV samples per "
        f"item, batch {info['batch']}, {info['epochs']} epochs), scored by `mna evaluate` on the held-out "
        f"members ({info['eval_points']} points each side, F@1 % in the unit-ball frame); seeds "
        f"{', '.join(map(str, info['seeds']))}: mean ± standard deviation.",
        f"- **per-shape**: `mna fit --preset fast`, {info['fit_steps']} steps, seed 0, L_orient off (not in "
        f"the paper), on {shapes}: mean ± standard deviation over the shapes; charts vs squares on "
        f"{', '.join(info['square_shapes'])} only (its MNA rows too).",
        "- CD is ours (squared distances, both directions, unit-ball frame); the paper's is x1e-4 in "
        "its own frame: compare directions, not values. F@1 % = F-score at 0.02 (1 % of the unit ball's "
        "diameter).",
        "- A claim is reproduced when its direction shows in the mean and in at least two thirds of the "
        "pairs (seeds or shapes); the other rules are stated in the claim's row.",
        "",
        "### Claims",
        "",
        paper.claims_table(claims),
        "",
    ]
    for setting in ("conditional", "per-shape"):
        parts += [f"### Ablations, {setting} (3 charts)", "", paper.ablation_table(rows, setting), "",
                  f"### Charts vs squares, {setting}", "", paper.squares_table(rows, setting), ""]
    parts += ["### Feed-forward topology (held-out members, 3 charts; MNA with L_dist, AtlasNet without)",
              "", topo_md, "", "Figure: `benchmarks/paper_figure.png` (and `.pdf`).", ""]
    return "\n".join(parts)


def figure(rows: list[dict], stem: Path, ks: tuple[int, ...]) -> None:
    """Four panels: F and metric distortion per ablation, F against K (charts vs squares),
    held-out F per topology."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    variants = list(paper.VARIANTS)
    for j, setting in enumerate(("conditional", "per-shape")):
        for a, key, label in ((ax[0, 0], "chamfer_pcl", "Chamfer (point cloud)"),
                              (ax[0, 1], "distortion_metric", "metric distortion")):
            stats = [paper.summary(paper.select(rows, setting=setting, variant=v, method="mna", charts=3), key)
                     for v in variants]
            a.bar([i + 0.4 * j for i in range(len(variants))], [m for m, _, _ in stats], 0.4,
                  yerr=[sd for _, sd, _ in stats], label=setting, capsize=3)
            a.set_xticks([i + 0.2 for i in range(len(variants))], variants, rotation=20)
            a.set_ylabel(label)
            a.set_title(f"Ablations: {label}")
            a.legend()
    ax[0, 0].set_yscale("log")
    ax[0, 1].set_yscale("log")
    for setting, style in (("conditional", "-"), ("per-shape", "--")):
        r = paper.select(rows, setting=setting, variant="full")
        r += [dict(x, ldist=False, variant="full") for x in paper.select(rows, setting=setting, variant="no_ldist")]
        r = paper.common_shapes(r)
        for method in ("mna", "atlasnet"):
            for ldist in (True, False):
                pts = [(k, paper.summary(paper.select(r, method=method, charts=k, ldist=ldist), "chamfer_pcl")[0])
                       for k in ks]
                pts = [(k, f) for k, f in pts if f == f]
                if pts:
                    ax[1, 0].plot(*zip(*pts), style, marker="o",
                                  label=f"{setting} {method}{' + L_dist' if ldist else ''}")
    ax[1, 0].set_xscale("log")
    ax[1, 0].set_xlabel("charts / squares K")
    ax[1, 0].set_yscale("log")
    ax[1, 0].set_ylabel("Chamfer (point cloud)")
    ax[1, 0].set_title("Charts vs squares")
    ax[1, 0].legend(fontsize=7)
    _, scores = paper.topology_table(rows)
    names = list(scores)
    for off, method, label in ((-0.2, "mna", "MNA (charts)"), (0.2, "atlasnet", "AtlasNet (squares)")):
        ax[1, 1].bar([i + off for i in range(len(names))], [scores[t][method]["chamfer_mesh"] for t in names], 0.4,
                     label=label)
    ax[1, 1].set_xticks(range(len(names)), names)
    ax[1, 1].set_ylabel("held-out Chamfer (mesh), lower is better")
    ax[1, 1].set_title("Feed-forward, per topology (3 charts)")
    ax[1, 1].legend()
    fig.tight_layout()
    stem.parent.mkdir(parents=True, exist_ok=True)
    for ext in ("png", "pdf"):
        tmp = stem.with_name(f".{stem.name}.tmp.{ext}")
        fig.savefig(tmp, dpi=120)
        tmp.replace(stem.with_suffix(f".{ext}"))
    plt.close(fig)
