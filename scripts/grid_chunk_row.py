"""The results/grid/README.md row of one chunk of a grid rerun, against the committed run.

    python scripts/grid_chunk_row.py K --dir results/grid/<commit> --code "<commit> (...)" \
        --run "2026-12-03 (twentieth session), 2 workers, about 7 min" [--planner mirror] [--insert]

Reads ``DIR/<planner>-chunkKK-of-64.parquet`` and the committed tables of the same chunk
(``results/grid/<planner>-``, ``mirror-guided-`` and ``hybrid-astar-chunkKK-of-64.parquet``)
and prints the row: the chunk's slots, success against the committed run (cases gained
and lost), the other two planners' success, the failure causes, switches and parking
time where both runs park, collisions, errors and worker time. ``--insert`` also puts
it after the row of chunk K - 1 of the same folder in results/grid/README.md and counts
the chunk in docs/evaluation.md ("chunks 1 to K of 64") where it counts them. ``--code`` and ``--run`` are
the row's second column and the start of its third, as the person running it words them.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from evaluation.causes import cause_of

ROOT = Path(__file__).resolve().parents[1]
GRID = ROOT / "results" / "grid"
CAUSES = {  # failure cause -> (one case, several)
    "gave_up": ("gives up", "give up"),
    "no_iso_pose": ("admits no ISO pose", "admit no ISO pose"),
    "parked_outside_margin": ("ends outside a margin", "end outside a margin"),
    "timeout": ("runs out of its 180 s", "run out of their 180 s"),
    "collision": ("collides", "collide"),
    "out_of_scene": ("leaves the scene", "leave the scene"),
    "error": ("raises an error", "raise an error"),
}


def pct(s: pd.Series) -> str:
    return f"{100 * s.mean():.1f} %"


def slots(df: pd.DataFrame) -> str:
    """The chunk's slots, road by road in the grid's order (parallel, reverse, angle; wider
    roads first): 'The 6.0 m road's reverse slots of 1.87-1.97 m'."""
    parts = []
    kinds = {"parallel": 0, "reverse": 1, "angle": 2}
    groups = sorted(df.groupby(["road_width", "parking_type"]), key=lambda kv: (kinds[kv[0][1]], -kv[0][0]))
    for (rw, kind), g in groups:
        size = g.slot_length if kind == "parallel" else g.slot_width
        lo, hi = size.min(), size.max()
        span = f"{lo:.2f}-{hi:.2f} m" if lo != hi else f"{lo:.2f} m"
        count = f" ({len(g):,} cases)" if len(groups) > 1 else ""
        parts.append(f"the {rw:.1f} m road's {kind} slots of {span}{count}")
    text = "; ".join(parts)
    return text[0].upper() + text[1:]


def against(new: float, old: float, fmt: str, unit: str, unit_again: bool) -> tuple[str, bool]:
    """'1.77 switches against 1.79' or '15.8 s against 15.9 s'; the flag: both print alike."""
    a, b = f"{new:{fmt}}", f"{old:{fmt}}"
    if a == b:
        return f"{a}{unit}", True
    return f"{a}{unit} against {b}{unit if unit_again else ''}", False


def row(k: int, folder: Path, planner: str, code: str, run: str) -> str:
    name = f"{planner}-chunk{k:02d}-of-64.parquet"
    new = pd.read_parquet(folder / name)
    old = pd.read_parquet(GRID / name)
    guided = pd.read_parquet(GRID / f"mirror-guided-chunk{k:02d}-of-64.parquet")
    astar = pd.read_parquet(GRID / f"hybrid-astar-chunk{k:02d}-of-64.parquet")
    if list(new.case_id) != list(old.case_id):
        raise ValueError(f"{name}: the rerun and the committed run hold different cases")
    ok_n, ok_o = new.success.to_numpy(bool), old.success.to_numpy(bool)
    gained, lost = int((ok_n & ~ok_o).sum()), int((~ok_n & ok_o).sum())
    same = pct(new.success) == pct(old.success)
    verdict = "as in the committed run" if same else f"against {pct(old.success)} in the committed run"
    causes = new.failure_cause.dropna().map(cause_of).value_counts()
    said = [f"{c} {CAUSES.get(cause, (cause, cause))[c != 1]}" for cause, c in causes.items()]
    rest = ""
    if said:
        rest = "; of the rest, " + (", ".join(said[:-1]) + " and " + said[-1] if len(said) > 1 else said[0])
    both = ok_n & ok_o
    where = ""
    if both.any():
        sw, sw_same = against(new.switches[both].mean(), old.switches[both].mean(), ".2f", " switches", False)
        t, t_same = against(new.parking_time_s[both].mean(), old.parking_time_s[both].mean(), ".1f", " s", True)
        if sw_same and t_same:
            pair = f"{sw} and {t} in both"
        elif sw_same:
            pair = f"{sw} in both and {t}"
        elif t_same:
            pair = f"{sw} and {t} in both"
        else:
            pair = f"{sw} and {t}"
        where = f"; where both runs park ({int(both.sum()):,}) {pair}"
    hours = f"{new.episode_wall_s.sum() / 3600:.2f} h of worker time against {old.episode_wall_s.sum() / 3600:.2f} h"
    return (
        f"| `{name}` | {code} | {run}. {slots(new)}: {pct(new.success)} of {len(new):,} park, {verdict} "
        f"({gained} gained, {lost} lost; `mirror-guided` {pct(guided.success)}, hybrid A* {pct(astar.success)})"
        f"{rest}{where}; {int(new.collision.sum())} collisions, {int(new.error.notna().sum())} errors; {hours} "
        "(unpaired) |"
    )


def insert(k: int, folder: Path, planner: str, text: str) -> None:
    """``text`` after chunk K - 1's row of ``folder`` in results/grid/README.md; chunk K
    counted in docs/evaluation.md."""
    readme = GRID / "README.md"
    lines = readme.read_text().split("\n")
    tag = folder.name
    mine = lambda j: f"| `{planner}-chunk{j:02d}-of-64.parquet` | {tag}"  # noqa: E731
    if any(line.startswith(mine(k)) for line in lines):
        raise ValueError(f"results/grid/README.md already has chunk {k}'s row of {tag}")
    prev = [i for i, line in enumerate(lines) if line.startswith(mine(k - 1))]
    if len(prev) != 1:
        raise ValueError(f"results/grid/README.md: expected one row of chunk {k - 1} of {tag}, found {len(prev)}")
    doc = ROOT / "docs" / "evaluation.md"
    s = doc.read_text()
    lines.insert(prev[0] + 1, text)
    readme.write_text("\n".join(lines))
    if f"chunks 1 to {k - 1} of 64" in s:
        doc.write_text(s.replace(f"chunks 1 to {k - 1} of 64", f"chunks 1 to {k} of 64"))
    else:  # a rerun that docs/evaluation.md does not count chunk by chunk
        print(f"note: docs/evaluation.md does not say 'chunks 1 to {k - 1} of 64'; left as it is", file=sys.stderr)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("chunk", type=int)
    ap.add_argument("--dir", required=True, help="the rerun's folder, e.g. results/grid/<commit>")
    ap.add_argument("--planner", default="mirror")
    ap.add_argument("--code", required=True, help="the row's code column")
    ap.add_argument("--run", required=True, help="the start of the row's run column: date, session, workers, time")
    ap.add_argument("--insert", action="store_true")
    a = ap.parse_args()
    text = row(a.chunk, Path(a.dir), a.planner, a.code, a.run)
    print(text)
    if a.insert:
        insert(a.chunk, Path(a.dir), a.planner, text)


if __name__ == "__main__":
    main()
