"""How far each linearised model's prediction lies from the truth: the first planning call
of every smoke case, planned with the paper's fixed-angle linearisation (Eqs. 22-32,
``mirror-paper``: as before 2026-12-05, 1 m/s in its speed terms about the mean of the
start and goal headings, and as now, the previous round's speeds and mean heading) and
with the Jacobians about each rollout (SCP, ``mirror-multistart``).

For every QP solved in that call, the states the QP predicts are compared with the
truth model's rollout of the same commands (in the planned frame): the largest position
and heading gaps along the horizon. A model whose predictions are metres off cannot tell
the MIQP where the car will be, whatever the cost and the constraints say.

    python scripts/linearisation_error.py [--out docs/img/linearisation_error.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np

import mirrorpark_env  # noqa: F401  (registers MirrorPark-v0)
from mirrorpark_env.grid import default_grid_cases
from planners.mirror.config import MirrorPlannerConfig, multistart_config, paper_config
from planners.mirror.frames import XI_TH, to_planned
from planners.mirror.planner import MirrorPlanner

VARIANTS = {
    "paper, 1 m/s and the ends' mean heading (before 2026-12-05)": paper_config(
        paper_speed="nominal", paper_angle="ends"
    ),
    "paper, the previous round's speeds and mean heading": paper_config(),
    "SCP (Jacobians about each rollout)": multistart_config(),
}


def gaps(cfg: MirrorPlannerConfig, cases) -> np.ndarray:
    """(position gap [m], heading gap [rad]) of every QP of the cases' first calls."""
    env = gym.make("MirrorPark-v0")
    out = []
    for sc in cases:
        _, info = env.reset(options={"scenario": sc})
        planner = MirrorPlanner(info["geometry"], cfg)
        solved: list[np.ndarray] = []
        solve = planner._solve

        def keep(qp, disj, active, preferred, st, miqp, solve=solve, solved=solved):
            x = solve(qp, disj, active, preferred, st, miqp)
            if x is not None:
                solved.append(x)
            return x

        planner._solve = keep
        rollout = planner._rollout

        def compare(xi0, u_planned, cand, rollout=rollout, solved=solved, planner=planner):
            real = rollout(xi0, u_planned, cand)
            if solved and np.array_equal(solved[-1][planner.qp.u_index], u_planned):
                predicted = solved[-1][planner.qp.x_index]
                truth = to_planned(real, cand, cfg.model_substeps)
                dp = np.hypot(*(predicted[:, :2] - truth[:, :2]).T).max()
                dth = np.abs(predicted[:, XI_TH] - truth[:, XI_TH]).max()
                out.append((dp, dth))
            return real

        planner._rollout = compare
        planner.plan(info["vehicle_state"])
    env.close()
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/linearisation_error.png"))
    args = ap.parse_args()
    cases = default_grid_cases().sample("smoke")
    results = {name: gaps(cfg, cases) for name, cfg in VARIANTS.items()}
    for name, g in results.items():
        p50, p90 = np.percentile(g[:, 0], [50, 90])
        h50, h90 = np.degrees(np.percentile(g[:, 1], [50, 90]))
        print(
            f"{name}: {len(g)} QPs; position gap median {p50:.3f} m, p90 {p90:.3f} m; "
            f"heading gap median {h50:.1f} deg, p90 {h90:.1f} deg"
        )
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    bins = np.logspace(-4, 2, 49)
    for name, g in results.items():
        ax.hist(np.maximum(g[:, 0], 1e-4), bins=bins, alpha=0.6, label=f"{name} ({len(g)} QPs)")
    ax.set_xscale("log")
    ax.set_xlabel("largest position gap, QP prediction vs truth rollout [m]")
    ax.set_ylabel("QPs")
    ax.set_title("First planning call of each smoke case", fontsize=9)
    ax.legend(fontsize=7)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110, bbox_inches="tight")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
