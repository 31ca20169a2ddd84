"""Which cases to run: a named grid sample or a user's case file (JSON or CSV)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from mirrorpark_env.grid import default_grid_cases
from mirrorpark_env.layout_io import load_many
from mirrorpark_env.scenario import Scenario
from mirrorpark_env.vehicle import vehicle_named

from .runner import unique

CASE_FIELDS = ("parking_type", "road_width", "slot_length", "slot_width", "theta0_deg", "y0")


def from_sample(name: str, types: list[str] | None = None, seed: int | None = None) -> list[Scenario]:
    """``smoke`` (30 per type), ``standard`` (500 per type) or ``full`` (70,434 cases)."""
    grid = default_grid_cases()
    idx = grid.sample_indices(name, seed=seed, types=tuple(types) if types else None)
    if types and name == "full":
        idx = [i for i in idx if grid.scenario(int(i)).parking_type.value in types]
    return [grid.scenario(int(i)) for i in idx]


def chunk(items: list, spec: str | None) -> list:
    """Chunk ``K/N`` (1-based) of ``items``: the K-th of N contiguous, near-equal slices.

    The same list and spec give the same cases on any machine, so a long run can go in
    pieces, a session each, and its pieces be committed one by one."""
    if not spec:
        return items
    try:
        k, n = (int(v) for v in spec.split("/"))
    except ValueError:
        raise ValueError(f"--chunk: expected K/N with whole numbers, e.g. 3/16, got {spec!r}") from None
    if not 1 <= k <= n:
        raise ValueError(f"--chunk: K must be in 1..N, got {spec!r}")
    lo, hi = (len(items) * (k - 1)) // n, (len(items) * k) // n
    if lo == hi:
        raise ValueError(f"--chunk {spec}: holds no case ({len(items)} case(s) in {n} chunks); use fewer chunks")
    return items[lo:hi]


def cases_from(sample: str, case_file: str | None, types: list[str] | None) -> tuple[list[Scenario], int]:
    """A case file's cases (filtered by ``types``, repeats dropped) or a grid sample's, and
    how many repeats were dropped."""

    if not case_file:
        return from_sample(sample, types=types), 0
    cases = load_case_file(case_file)
    if types:
        cases = [sc for sc in cases if sc.parking_type.value in types]
        if not cases:
            raise ValueError(f"{case_file}: no case of type {', '.join(types)}")
    return unique(cases)


def layouts_from(paths: list[str], types: list[str] | None, vehicle: str | None = None) -> tuple[list, int]:
    """The layouts in files and folders (those with a slot of ``types`` if given), repeated
    names dropped, and how many were dropped. ``vehicle``: every layout's car (a name or a
    YAML file, ``vehicle.vehicle_named``) instead of its file's. Invalid files are refused
    all together, each named with its problem."""

    layouts = load_many(paths, vehicle_named(vehicle) if vehicle is not None else None)
    if types:
        layouts = [lay for lay in layouts if lay.slot is not None and lay.slot.parking_type.value in types]
        if not layouts:
            raise ValueError(f"--layouts: no layout with a slot of type {', '.join(types)}")
    return unique(layouts)


def load_case_file(path: str | Path) -> list[Scenario]:
    """Cases from a JSON list of objects or a CSV with a header row, fields ``CASE_FIELDS``.

    Raises ``ValueError`` naming the file, the case (1-based) and the field on any problem.
    """
    p = Path(path)
    if p.suffix.lower() not in (".json", ".csv"):
        raise ValueError(f"{p}: case file must end in .json or .csv")
    try:
        text = p.read_bytes().decode("utf-8")
    except OSError as err:
        raise ValueError(f"{p}: cannot read case file ({err.strerror})") from None
    except UnicodeDecodeError as err:
        raise ValueError(f"{p}: not UTF-8 text (byte {err.start})") from None
    if p.suffix.lower() == ".json":
        try:
            rows = json.loads(text)
        except json.JSONDecodeError as err:
            raise ValueError(f"{p}: not valid JSON: {err}") from None
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise ValueError(f"{p}: expected a JSON list of objects with fields {', '.join(CASE_FIELDS)}")
    else:
        rows = list(csv.DictReader(text.splitlines()))
        if rows and set(CASE_FIELDS) - set(rows[0]):
            missing = sorted(set(CASE_FIELDS) - set(rows[0]))
            raise ValueError(f"{p}: CSV header lacks {', '.join(missing)}; needs {', '.join(CASE_FIELDS)}")
    if not rows:
        raise ValueError(f"{p}: no cases")
    out = []
    for n, row in enumerate(rows, 1):
        if None in row:  # csv.DictReader: more values than the header names
            raise ValueError(f"{p}: case {n}: more values than the header names")
        bad = [k for k, v in row.items() if isinstance(v, bool) or isinstance(v, (list, dict))]
        if bad:
            raise ValueError(f"{p}: case {n}: {bad[0]}: expected a number or a name, got {row[bad[0]]!r}")
        missing = [f for f in CASE_FIELDS if f not in row or row[f] in ("", None)]
        if missing:
            raise ValueError(f"{p}: case {n}: missing field(s) {', '.join(missing)}")
        extra = sorted(set(row) - set(CASE_FIELDS) - {"start_x_offset"})
        if extra:
            raise ValueError(f"{p}: case {n}: unknown field(s) {', '.join(extra)}; allowed: {', '.join(CASE_FIELDS)}")
        try:
            sc = Scenario.from_degrees(
                row["parking_type"],
                row["road_width"],
                row["slot_length"],
                row["slot_width"],
                row["theta0_deg"],
                row["y0"],
                row.get("start_x_offset", 0.0) or 0.0,
            )
            sc.build()  # impossible geometry is rejected here, with the field named
        except ValueError as err:
            raise ValueError(f"{p}: case {n}: {err}") from None
        out.append(sc)
    return out
