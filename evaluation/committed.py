"""The committed full-grid rows of a planner, for exactly a run's cases (``compare --against``).

``results/grid/`` holds every grid case's row of the main planners, chunk by chunk. A
table's code stamp (``code_stamp.code_id``) is in its metadata (the environments it was run
in, ``code``) or, for tables committed before stamps were recorded, in
``results/grid/code_ids.json`` (file name -> planner, commit, code_id), which wins where it
names a file. Rows whose stamp is
not the installed code's are refused unless the caller allows other code: they would pass
for what this install's planner does.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from .code_stamp import code_id
from .store import environments_of

GRID_DIR = Path(__file__).resolve().parents[1] / "results" / "grid"
MANIFEST = "code_ids.json"


def _stamp(path: Path, planner: str, manifest: dict) -> tuple[str | None, str]:
    """(code_id, commit or '') of the table at ``path``: the manifest's where it names the
    file (a curated record, which may also say that later code, changed only in what decides
    no row, gives the same rows), else its metadata's."""

    entry = manifest.get(path.name)
    if entry is not None:
        return entry.get("code_id"), entry.get("commit", "")
    codes = {e.get("code") for e in environments_of(path) if e.get("planner") == planner and e.get("code")}
    return (codes.pop(), "") if len(codes) == 1 else (None, "")


def committed_rows(
    planner: str, case_ids: set[str], grid_dir: str | Path | None = None, allow_other_code: bool = False
) -> tuple[pd.DataFrame, bool]:
    """The committed rows of ``planner`` for ``case_ids`` and whether they came from the
    installed code. Raises ``ValueError`` (one line) where a case has no committed row, or
    where the rows came from other code and ``allow_other_code`` is not set."""

    folder = Path(grid_dir) if grid_dir is not None else GRID_DIR
    files = sorted(folder.glob(f"{planner}-chunk*-of-*.parquet")) or sorted(folder.glob(f"{planner}.parquet"))
    if not files:
        have = sorted({p.name.split("-chunk")[0] for p in folder.glob("*.parquet")})
        raise ValueError(
            f"--against: no committed rows of {planner!r} in {folder} (there: {', '.join(have) or 'none'})"
        )
    manifest_path = folder / MANIFEST
    manifest = json.loads(manifest_path.read_text()) if manifest_path.exists() else {}
    frames, used = [], []
    for f in files:
        df = pd.read_parquet(f)
        pick = df[df["case_id"].isin(case_ids) & (df["planner"] == planner)]
        if len(pick):
            frames.append(pick)
            used.append(f)
    rows = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["case_id"])
    missing = sorted(case_ids - set(rows["case_id"]))
    if missing:
        raise ValueError(
            f"--against {planner}: {len(missing)} of the run's {len(case_ids)} cases have no committed row "
            f"(e.g. {missing[0]}); the committed rows are of grid cases only"
        )
    now = code_id(planner)
    stamps = {_stamp(f, planner, manifest) for f in used}
    other = sorted({f"{c or 'unstamped'}{f' of {commit}' if commit else ''}" for c, commit in stamps if c != now})
    if other and not allow_other_code:
        raise ValueError(
            f"--against {planner}: its committed rows came from other code ({', '.join(other)}) than the installed "
            f"{planner} (code {now}): rerun the grid (scripts/grid_run.sh {planner}) or pass --allow-other-code"
        )
    return rows.drop_duplicates("case_id"), not other
