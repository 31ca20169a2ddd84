"""Results that survive: rows appended as cases finish, resumable, compacted to Parquet.

Each finished case is one JSON line in ``journal.jsonl``, flushed as it is written, so an
interrupted run loses no finished case. ``table()`` reads the journal; ``compact()``
writes ``results.parquet``. A run over the same folder skips the (planner, case) pairs
already there.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import pandas as pd


class ResultStore:
    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.journal = self.folder / "journal.jsonl"
        self.parquet = self.folder / "results.parquet"

    def done(self) -> set[tuple[str, str]]:
        """(planner, case_id) pairs with a recorded row (errors included)."""
        return {(r["planner"], r["case_id"]) for r in self._rows()}

    def append(self, row: dict[str, Any]) -> None:
        line = json.dumps(row, default=_json_default) + "\n"
        if self.journal.exists() and self.journal.stat().st_size:
            with self.journal.open("rb") as f:  # a line cut short by an interruption
                f.seek(-1, os.SEEK_END)  # stays on its own line, and is skipped
                if f.read(1) != b"\n":
                    line = "\n" + line
        with self.journal.open("a") as f:
            f.write(line)
            f.flush()
            os.fsync(f.fileno())

    def _rows(self) -> list[dict[str, Any]]:
        if not self.journal.exists():
            return []
        rows = []
        with self.journal.open() as f:
            for line in f:
                line = line.strip()
                if not line:
                    continue
                try:
                    rows.append(json.loads(line))
                except json.JSONDecodeError:
                    continue  # a line cut short by an interruption: that case reruns
        return rows

    def table(self) -> pd.DataFrame:
        rows = self._rows()
        df = pd.DataFrame(rows)
        if len(df):
            df = df.drop_duplicates(subset=["planner", "case_id"], keep="last").reset_index(drop=True)
        return df

    def compact(self) -> Path:
        df = self.table()
        df.to_parquet(self.parquet, index=False)
        return self.parquet


def _json_default(o):
    if hasattr(o, "item"):
        return o.item()
    if hasattr(o, "tolist"):
        return o.tolist()
    if isinstance(o, float) and math.isnan(o):
        return None
    return str(o)


def read_results(paths: list[str | Path]) -> pd.DataFrame:
    """Results from folders (journal or Parquet) or Parquet files, concatenated."""
    frames = []
    for p in map(Path, paths):
        if p.is_dir():
            store = ResultStore(p)
            frames.append(store.table() if store.journal.exists() else pd.read_parquet(store.parquet))
        elif p.suffix == ".parquet":
            frames.append(pd.read_parquet(p))
        elif p.suffix == ".jsonl":
            frames.append(pd.read_json(p, lines=True))
        else:
            raise ValueError(f"{p}: expected a results folder, a .parquet or a .jsonl file")
    if not frames:
        raise ValueError("no results given")
    return pd.concat(frames, ignore_index=True)
