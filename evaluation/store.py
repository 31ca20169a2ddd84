"""Results that survive: rows appended as cases finish, resumable, stored as Parquet.

Each finished case is first one JSON line in ``journal.jsonl``, flushed and synced as it
is written, so an interrupted run loses no finished case. Every ``part_rows`` rows the
journal rolls over into a Parquet part (``parts/part-NNNNN.parquet``, written whole and
renamed into place) and starts afresh. ``table()`` reads parts and journal;
``compact()`` writes them all to ``results.parquet``. A run over the same folder skips
the (planner, case) pairs already there. A crash between writing a part and clearing the
journal leaves rows twice; readers keep one.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import pandas as pd


class ResultStore:
    def __init__(self, folder: str | Path, part_rows: int = 25):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.journal = self.folder / "journal.jsonl"
        self.parts = self.folder / "parts"
        self.parquet = self.folder / "results.parquet"
        self.part_rows = part_rows
        self._pending = len(self._rows())

    def done(self) -> set[tuple[str, str]]:
        """(planner, case_id) pairs with a recorded row (errors included)."""
        df = self.table()
        return set(zip(df["planner"], df["case_id"])) if len(df) else set()

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
        self._pending += 1
        if self._pending >= self.part_rows:
            self.roll()

    def roll(self) -> None:
        """Move the journal's rows into a new Parquet part."""
        rows = self._rows()
        if rows:
            self.parts.mkdir(exist_ok=True)
            n = len(list(self.parts.glob("part-*.parquet")))
            tmp = self.parts / f".part-{n:05d}.tmp"
            pd.DataFrame(rows).to_parquet(tmp, index=False)
            tmp.rename(self.parts / f"part-{n:05d}.parquet")
        self.journal.unlink(missing_ok=True)
        self._pending = 0

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
        frames = [pd.read_parquet(p) for p in sorted(self.parts.glob("part-*.parquet"))] if self.parts.exists() else []
        rows = self._rows()
        if rows:
            frames.append(pd.DataFrame(rows))
        df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
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
            df = store.table()
            frames.append(df if len(df) or not store.parquet.exists() else pd.read_parquet(store.parquet))
        elif p.suffix == ".parquet":
            frames.append(pd.read_parquet(p))
        elif p.suffix == ".jsonl":
            frames.append(pd.read_json(p, lines=True))
        else:
            raise ValueError(f"{p}: expected a results folder, a .parquet or a .jsonl file")
    if not frames:
        raise ValueError("no results given")
    return pd.concat(frames, ignore_index=True)
