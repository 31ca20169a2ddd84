"""Put the rows of a partial grid rerun into the committed chunk tables, case by case.

A change that alters only some cases' plans (``scripts/grid_window_cases.py`` lists them)
is rerun on those cases alone (``mirrorpark evaluate --cases CSV --export DIR``). This
replaces each of those cases' rows in the chunk tables ``results/grid/PLANNER-chunk*``,
keeping every table's row order and columns, and says per chunk how many rows it replaced.
Run: ``python scripts/grid_splice.py RERUN.parquet [PLANNER=mirror] [DIR=results/grid]``.
"""

from __future__ import annotations

import glob
import sys

import pandas as pd


def main(rerun: str, planner: str = "mirror", folder: str = "results/grid") -> None:
    new = pd.read_parquet(rerun)
    if new.case_id.duplicated().any():
        raise SystemExit(f"{rerun}: a case appears twice")
    new = new.set_index("case_id", drop=False)
    changed = []  # (path, table, rows replaced): written only once every rerun case is placed
    for path in sorted(glob.glob(f"{folder}/{planner}-chunk*.parquet")):
        old = pd.read_parquet(path)
        hit = old.case_id.isin(new.index)
        if not hit.any():
            continue
        if list(old.columns) != list(new.columns):
            raise SystemExit(f"{path}: columns differ from {rerun}'s")
        rows = new.loc[old.case_id[hit]]
        out = old.copy()
        out.loc[hit] = rows.set_index(old.index[hit]).astype(old.dtypes.to_dict())
        changed.append((path, out, int(hit.sum())))
    placed = sum(n for _, _, n in changed)
    if placed != len(new):
        raise SystemExit(f"only {placed} of {len(new)} rerun cases are in {folder}'s {planner} tables; nothing written")
    for path, out, n in changed:
        out.to_parquet(path, index=False)
        print(f"{path}: {n} of {len(out)} rows replaced")
    print(f"{placed} rows replaced")


if __name__ == "__main__":
    main(*sys.argv[1:])
