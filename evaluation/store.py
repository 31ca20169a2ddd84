"""Results that survive: rows appended as cases finish, resumable, stored as Parquet.

Each finished case is first one JSON line in ``journal.jsonl``, flushed and synced as it
is written, so an interrupted run loses no finished case. Every ``part_rows`` rows the
journal rolls over into a Parquet part (``parts/part-NNNNNN-XXXXXXXX.parquet``: a
sequence number and a random tag, written whole and linked into place, never over
another file) and starts afresh. ``compact()`` writes every row to ``results.parquet``
(atomically) and only then removes the parts and the journal.

``table()`` reads all three: ``results.parquet``, the parts and the journal, so a run
resumes from any of them and never redoes or overwrites a finished row. Damage is
reported (a ``StoreWarning`` naming the file and line), skipped, and kept aside, never
fatal: a journal line that is not a valid row goes to ``journal.rejected.jsonl`` (its
case reruns); an unreadable Parquet file is renamed ``*.unreadable``. A crash between
writing a part and clearing the journal leaves rows twice; readers keep one.
"""

from __future__ import annotations

import json
import math
import os
import secrets
import socket
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from . import provenance
from .code_stamp import code_id
from .schema import EXPORT_COLUMNS, exported_values, type_error

KEY = ["planner", "case_id"]
# What every row has, an error row too (``episode.run_case``; exported tables keep them all):
# a table without them is not MirrorPark's results, and readers would fail on it.
REQUIRED = (
    *KEY,
    *("parking_type", "road_width", "slot_length", "slot_width", "theta0_deg"),
    *("success", "failed_criterion", "feasible", "failure_cause"),
)
ENVIRONMENTS_KEY = b"mirrorpark.environments"  # an exported table's metadata: where it ran


class StoreWarning(UserWarning):
    """Damage found in a results folder: reported, skipped, kept aside."""


def check_row(row: Any) -> str | None:
    """Why ``row`` (a decoded journal line) is not a valid result row, or None."""
    if not isinstance(row, dict):
        return f"not a JSON object ({type(row).__name__})"
    for k in KEY:
        if not isinstance(row.get(k), str) or not row[k]:
            return f"{k!r} missing or not a non-empty string"
    return type_error(row)


def check_columns(df: pd.DataFrame, path: str | Path, required: tuple[str, ...] = REQUIRED) -> None:
    """Refuse a table that lacks the ``required`` columns (by default those every result row
    has), naming the file and them."""
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise ValueError(f"{path}: not a MirrorPark results table: lacks the column(s) {', '.join(missing)}")


@contextmanager
def locked(folder: str | Path) -> Iterator[None]:
    """One run at a time in a results folder: ``.lock`` holds the owner's PID and host while it
    runs. Another run refuses ("OUT is in use by PID N on HOST"); a lock whose process no
    longer runs on this host (a run killed outright) is taken over with a warning."""
    path = Path(folder) / ".lock"
    me = f"{os.getpid()} {socket.gethostname()}"
    while True:
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            pid, host = _lock_owner(path)
            if _running(pid, host):
                raise ValueError(
                    f"{folder} is in use by PID {pid} on {host}: wait for that run, or give another --out"
                ) from None
            took = f"{folder}: took over the lock of PID {pid} on {host}, which no longer runs"
            warnings.warn(took, StoreWarning, stacklevel=3)
            path.unlink(missing_ok=True)
            continue
        with os.fdopen(fd, "w") as f:
            f.write(me)
        break
    try:
        yield
    finally:
        if _lock_owner(path) == (os.getpid(), socket.gethostname()):
            path.unlink(missing_ok=True)


def _lock_owner(path: Path) -> tuple[int, str]:
    """(PID, host) written in a lock file; (0, "?") where it cannot be read."""
    try:
        pid, host = path.read_text().split(maxsplit=1)
        return int(pid), host.strip()
    except (OSError, ValueError):
        return 0, "?"


def _running(pid: int, host: str) -> bool:
    """Whether the lock's owner may still run: on another host, assumed so."""
    if host != socket.gethostname():
        return True
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class ResultStore:
    """One results folder. ``writable=False`` only reads (no folder made, nothing moved)."""

    def __init__(self, folder: str | Path, part_rows: int = 25, writable: bool = True):
        self.folder = Path(folder)
        self.writable = writable
        if self.folder.exists() and not self.folder.is_dir():
            raise ValueError(f"{self.folder}: results folder is a file")
        if writable:
            try:
                self.folder.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise ValueError(f"{self.folder}: cannot create the results folder ({err.strerror})") from None
            if not os.access(self.folder, os.W_OK):
                raise ValueError(f"{self.folder}: results folder is not writable")
        self.journal = self.folder / "journal.jsonl"
        self.rejected = self.folder / "journal.rejected.jsonl"
        self.parts = self.folder / "parts"
        self.parquet = self.folder / "results.parquet"
        self.environment_log = self.folder / "environment.jsonl"
        self.part_rows = part_rows
        for tmp in self.parts.glob(".part-*.tmp") if writable and self.parts.exists() else ():
            tmp.unlink(missing_ok=True)  # a part cut short by an interruption: its rows are in the journal
        self._pending = len(self._rows()[0])

    def record_environment(self, planner: str, cases: int) -> None:
        """Note what the run about to start runs on: one line per run."""
        record_environment(self.environment_log, planner, cases)

    def environments(self) -> list[dict[str, Any]]:
        """The runs' environments, oldest first (lines that do not parse are skipped)."""
        return read_environments(self.environment_log)

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
        with self.journal.open("a", encoding="utf-8") as f:
            f.write(line)
            f.flush()
            os.fsync(f.fileno())
        self._pending += 1
        if self._pending >= self.part_rows:
            self.roll()

    def roll(self) -> None:
        """Move the journal's rows into a new Parquet part (bad lines aside, then the journal goes)."""
        rows, bad = self._rows()
        if rows:
            self.parts.mkdir(exist_ok=True)
            _write_new(pd.DataFrame(rows), self.parts, self._next_part_name())
        self._keep_aside(bad)
        self.journal.unlink(missing_ok=True)
        self._pending = 0

    def _next_part_name(self) -> str:
        nums = [int(p.name.split("-")[1]) for p in self.parts.glob("part-*.parquet") if p.name.split("-")[1].isdigit()]
        return f"part-{max(nums, default=-1) + 1:06d}-{secrets.token_hex(4)}.parquet"

    def _rows(self) -> tuple[list[dict[str, Any]], list[tuple[int, bytes, str]]]:
        """Valid journal rows, and the bad lines as (line number, raw bytes, why)."""
        if not self.journal.exists():
            return [], []
        rows, bad = [], []
        with self.journal.open("rb") as f:
            for n, raw in enumerate(f, 1):
                if not raw.strip():
                    continue
                row, why = _json_line(raw)
                if why is None:
                    why = check_row(row)
                    if why is None:
                        rows.append(row)
                        continue
                bad.append((n, raw, why))
        return rows, bad

    def _keep_aside(self, bad: list[tuple[int, bytes, str]]) -> None:
        if not bad:
            return
        with self.rejected.open("ab") as f:
            for _, raw, _ in bad:
                f.write(raw if raw.endswith(b"\n") else raw + b"\n")
            f.flush()
            os.fsync(f.fileno())

    def _read_parquet(self, path: Path) -> pd.DataFrame | None:
        try:
            df = pd.read_parquet(path)
        except Exception as err:  # noqa: BLE001  (any damage: report and set aside, never fatal)
            what = f"{path}: unreadable ({type(err).__name__})"
            if self.writable:
                aside = path.with_name(path.name + ".unreadable")
                n = 1
                while aside.exists():  # an earlier damaged copy stays: set-aside files never replace each other
                    n += 1
                    aside = path.with_name(f"{path.name}.{n}.unreadable")
                path.rename(aside)
                what += f"; moved to {aside.name}, its cases rerun"
            warnings.warn(what, StoreWarning, stacklevel=3)
            return None
        check_columns(df, path, tuple(KEY))  # a foreign table: refused, not taken for results
        return df

    def table(self) -> pd.DataFrame:
        """Every finished row: results.parquet, then the parts, then the journal (last wins)."""
        files = [self.parquet] if self.parquet.exists() else []
        files += sorted(self.parts.glob("part-*.parquet")) if self.parts.exists() else []
        frames = [df for df in map(self._read_parquet, files) if df is not None and len(df)]
        rows, bad = self._rows()
        for n, _, why in bad:
            warnings.warn(f"{self.journal}:{n}: skipped, {why}; its case reruns", StoreWarning, stacklevel=2)
        if rows:
            frames.append(pd.DataFrame(rows))
        df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
        if len(df):
            df = df.drop_duplicates(subset=KEY, keep="last").reset_index(drop=True)
        return df

    def compact(self) -> Path:
        """All rows into results.parquet (written whole, then renamed), then parts and journal
        removed; bad journal lines are kept aside first."""
        df = self.table()
        if not len(df):
            return self.parquet
        tmp = self.folder / f".results-{secrets.token_hex(4)}.tmp"
        df.to_parquet(tmp, index=False)
        os.replace(tmp, self.parquet)
        self._keep_aside(self._rows()[1])
        self.journal.unlink(missing_ok=True)
        for p in self.parts.glob("part-*.parquet") if self.parts.exists() else ():
            p.unlink()
        self._pending = 0
        return self.parquet


def record_environment(log: Path, planner: str, cases: int) -> None:
    """Append to ``log`` what a run of ``planner`` on ``cases`` cases runs on
    (``provenance.environment``) and the code it runs (``provenance.source_id``, and the
    planner's own ``code_stamp.code_id``)."""
    env = provenance.environment()
    source = provenance.source_id(planner)
    line = {"id": provenance.environment_id(env), "planner": planner, "cases": cases, "source": source, **env}
    try:  # this planner's code alone (``compare --against`` checks it)
        line["code"] = code_id(planner)
    except Exception:  # noqa: BLE001  (a stamp it cannot take must not stop the run; the rows go unstamped)
        line["code"] = None
    line["source_files"] = provenance.source_files(planner)
    with log.open("a") as f:
        f.write(json.dumps(line) + "\n")


def read_environments(log: Path) -> list[dict[str, Any]]:
    """The lines of ``record_environment``'s ``log``, oldest first. A damaged line (not UTF-8,
    not a JSON object) is skipped with a ``StoreWarning`` naming the file and line, as the
    journal's are: it only describes runs, so a resume goes on without it."""
    if not log.exists():
        return []
    out = []
    for n, raw in enumerate(log.read_bytes().splitlines(), 1):
        if not raw.strip():
            continue
        line, why = _json_line(raw)
        if why is not None or not isinstance(line, dict):
            warnings.warn(f"{log}:{n}: skipped, not a run's record (a JSON object)", StoreWarning, stacklevel=2)
            continue
        out.append(line)
    return out


def _json_line(raw: bytes) -> tuple[Any, str | None]:
    """One line of a JSON-lines file decoded: (value, None), or (None, why it is not one)."""
    try:
        return json.loads(raw.decode("utf-8")), None
    except UnicodeDecodeError:
        return None, "not UTF-8 text"
    except json.JSONDecodeError:
        return None, "not valid JSON (cut short by an interruption?)"
    except (ValueError, RecursionError):  # an integer too long, nesting too deep
        return None, "not readable JSON (too long a number or too deep)"


def _write_new(df: pd.DataFrame, folder: Path, name: str) -> Path:
    """Write ``df`` to ``folder/name`` whole; never replaces an existing file."""
    tmp = folder / f".{name}.{secrets.token_hex(4)}.tmp"
    df.to_parquet(tmp, index=False)
    final = folder / name
    os.link(tmp, final)  # fails if the name exists
    tmp.unlink()
    return final


def _json_default(o):
    if hasattr(o, "item"):
        return o.item()
    if hasattr(o, "tolist"):
        return o.tolist()
    if isinstance(o, float) and math.isnan(o):
        return None
    return str(o)


def read_results(paths: list[str | Path], required: tuple[str, ...] = tuple(KEY)) -> pd.DataFrame:
    """Results from run folders (journal, parts, results.parquet), folders of exported tables
    (``export_table``'s ``*.parquet``, e.g. a grid's chunks), or Parquet / JSON-lines files.

    Raises ``ValueError`` naming a path that is missing, of the wrong kind, empty, or
    without the ``required`` columns (the commands ask for ``REQUIRED``: a foreign table is
    refused in one line rather than failing half-way).
    """
    frames = []
    for p in map(Path, paths):
        if p.is_dir():
            if not any(p.iterdir()):
                raise ValueError(f"{p}: results folder is empty")
            store = ResultStore(p, writable=False)
            exported = sorted(p.glob("*.parquet"))
            if not (store.journal.exists() or store.parts.exists() or store.parquet.exists()) and exported:
                frames.append(read_results(exported, required))  # a folder of exported tables
                continue
            df = store.table()
        elif not p.exists():
            raise ValueError(f"{p}: no such results folder or file")
        elif p.suffix == ".parquet":
            try:
                df = pd.read_parquet(p)
            except Exception as err:  # noqa: BLE001
                raise ValueError(f"{p}: not a readable Parquet file ({type(err).__name__})") from None
        elif p.suffix == ".jsonl":
            try:
                df = pd.read_json(p, lines=True)
            except ValueError as err:
                raise ValueError(f"{p}: not a JSON-lines results file ({err})") from None
        else:
            raise ValueError(f"{p}: expected a results folder, a .parquet or a .jsonl file")
        if not len(df):
            raise ValueError(f"{p}: holds no result rows")
        check_columns(df, p, required)
        frames.append(df)
    if not frames:
        raise ValueError("no results given")
    return pd.concat(frames, ignore_index=True)


def export_table(
    df: pd.DataFrame,
    folder: str | Path,
    planner: str,
    chunk: str | None = None,
    environments: list[dict[str, Any]] | None = None,
) -> Path:
    """``df``'s rows in the exported columns (``schema.py``), sorted by case, to
    ``folder/<planner>[-chunkK-of-N].parquet`` (zstd; replaced whole, atomically).
    ``mirrorpark report`` reads such files directly. Per-call medians and maxima and steps
    are left out: they follow from what is kept.
    Of ``environments`` (``ResultStore.environments``), those the rows name go into the
    file's metadata under ``mirrorpark.environments`` (``environments_of`` reads them)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = planner.replace(":", "_").replace("/", "_")
    if chunk:
        k, n = chunk.split("/")
        name += f"-chunk{int(k):02d}-of-{int(n):02d}"
    out = exported_values(df[[c for c in EXPORT_COLUMNS if c in df.columns]].sort_values("case_id"))

    table = pa.Table.from_pandas(out, preserve_index=False)
    named = set(out["environment"].dropna()) if "environment" in out else set()
    envs, seen = [], set()
    for e in environments or []:  # the first run in each environment that the rows name
        if e.get("id") in named and e["id"] not in seen:
            seen.add(e["id"])
            envs.append(e)
    if envs:
        meta = dict(table.schema.metadata or {})
        meta[ENVIRONMENTS_KEY] = json.dumps(envs).encode()
        table = table.replace_schema_metadata(meta)
    tmp = folder / f".{name}.{secrets.token_hex(4)}.tmp"
    pq.write_table(table, tmp, compression="zstd", compression_level=19)
    os.replace(tmp, folder / f"{name}.parquet")
    return folder / f"{name}.parquet"


def environments_of(path: str | Path) -> list[dict[str, Any]]:
    """The environments an exported table was run in (empty where none were recorded)."""

    raw = (pq.read_schema(path).metadata or {}).get(ENVIRONMENTS_KEY)
    return json.loads(raw) if raw else []
