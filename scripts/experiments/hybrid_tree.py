"""Draw hybrid A*'s search trees on one case, coarse cells against the tuned ones
(docs/hybrid_astar.md, "Tuning": the figures of the two anomalies), or the tuned search's
trees on one layout file (the journal, 2026-12-07: lots' angled bays).

    python scripts/experiments/hybrid_tree.py CASE_ID OUT.png
    python scripts/experiments/hybrid_tree.py LAYOUT_FILE OUT.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mirrorpark_env import Scenario
from mirrorpark_env.layout_io import load_layout
from mirrorpark_env.vehicle import footprint
from planners.hybrid_astar.search import HybridAStar, HybridAStarConfig


def draw(ax, g, cfg: HybridAStarConfig, title: str, start=None, whole: bool = False) -> None:
    hs = HybridAStar(g, cfg, keep_trees=True)
    path, st = hs.plan(start if start is not None else (g.start.x, g.start.y, g.start.theta))
    for poly in g.obstacles.polygons:
        ax.fill(*np.asarray(poly).T, color="0.75", lw=0)
    for backward, nodes in hs.last_trees:
        colour = "tab:orange" if backward else "tab:blue"
        for n in nodes[1:]:
            seg = np.vstack([nodes[n.parent].pose, n.samples])
            ax.plot(seg[:, 0], seg[:, 1], lw=0.3, color=colour, alpha=0.5)
    for pose, c in ((start if start is not None else g.start, "tab:green"), (g.target, "tab:red")):
        x, y, th = (pose.x, pose.y, pose.theta) if hasattr(pose, "x") else pose
        ax.fill(*footprint(g.vehicle, np.array([x]), np.array([y]), np.array([th]))[0].T, fill=False, ec=c)
    if path is not None:
        ax.plot(path.poses[:, 0], path.poses[:, 1], color="k", lw=1.2)
    n = sum(len(t) for _, t in hs.last_trees)
    ax.set_title(f"{title}: {st.status}, {st.iterations} expansions, {n} nodes", fontsize=8)
    x0, x1, y0, y1 = hs.window
    ax.set_xlim(x0 if whole else max(x0, -6), x1 if whole else min(x1, 12))
    ax.set_ylim(y0 if whole else max(y0, -3), y1 if whole else min(y1, 5.5))
    ax.set_aspect("equal")


def main() -> None:
    case, out = sys.argv[1], sys.argv[2]
    if Path(case).is_file():
        lay = load_layout(case)
        fig, ax = plt.subplots(figsize=(8, 7))
        draw(ax, lay.build(), HybridAStarConfig(), lay.name, start=lay.start, whole=True)
        fig.savefig(out, dpi=110)
        return
    g = Scenario.from_case_id(case).build()
    fig, axes = plt.subplots(2, 1, figsize=(7, 6.5))
    draw(axes[0], g, HybridAStarConfig(fine_gap=0.0, heuristic_weight=1.5), "5 deg cells everywhere (before)")
    draw(axes[1], g, HybridAStarConfig(), "1 deg cells where the car is tight (now)")
    fig.suptitle(f"{case} (backward search orange, forward blue)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main()
