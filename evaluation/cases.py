"""Which cases to run: a named grid sample or a user's case file (JSON or CSV)."""

from __future__ import annotations

import sys
from pathlib import Path

from mirrorpark_env.grid import default_grid_cases
from mirrorpark_env.layout_io import load_many
from mirrorpark_env.scenario import Scenario
from mirrorpark_env.textfile import csv_rows, parse_json, read_text
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


class _Pairs(tuple):
    """A JSON object of a case file as its (key, value) pairs: hashable, so that a file's
    repeated cases are one object in memory and are built once. Equal only with the same
    types too: ``true`` must not pass for an equal ``1`` (nor ``1`` for ``1.0``'s row)."""

    def _typed(self) -> tuple:
        return tuple((k, type(v), v) for k, v in self)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Pairs) and self._typed() == other._typed()

    def __ne__(self, other: object) -> bool:
        return not self == other

    def __hash__(self) -> int:
        return hash(self._typed())


def load_case_file(path: str | Path) -> list[Scenario]:
    """Cases from a JSON list of objects or a CSV with a header row, fields ``CASE_FIELDS``
    (UTF-8, with or without a byte-order mark), in the file's order, repeats included.

    A row written again (the same text) is the same ``Scenario``, validated and built once:
    a file of a million repeated cases loads in seconds. Raises ``ValueError`` naming the
    file, the case (1-based) and the field on any problem.
    """
    p = Path(path)
    if p.suffix.lower() not in (".json", ".csv"):
        raise ValueError(f"{p}: case file must end in .json or .csv")
    text = read_text(p, "case file")
    if p.suffix.lower() == ".json":
        seen: dict = {}
        rows = parse_json(text, p, object_pairs_hook=lambda pairs: _interned(_Pairs(pairs), seen))
        del text, seen
        if not isinstance(rows, list) or not all(isinstance(r, _Pairs) for r in rows):
            raise ValueError(f"{p}: expected a JSON list of objects with fields {', '.join(CASE_FIELDS)}")
        header = None
    else:
        rows = csv_rows(text, p)
        header = next(rows, None)
        if header is not None:
            header = [h.strip() for h in header]
            if set(CASE_FIELDS) - set(header):
                missing = sorted(set(CASE_FIELDS) - set(header))
                raise ValueError(f"{p}: CSV header lacks {', '.join(missing)}; needs {', '.join(CASE_FIELDS)}")
    out: list[Scenario] = []
    built: dict = {}
    n = 0
    for raw in rows:
        if header is not None and not any(v.strip() for v in raw):
            continue  # a blank line
        n += 1
        key = raw if header is None else tuple(raw)
        try:
            sc = built.get(key)
        except TypeError:  # a JSON value that is a list: ``_case`` refuses it
            sc = None
        if sc is None:
            sc = _case(p, n, dict(raw) if header is None else _csv_row(p, n, header, raw))
            built[key] = sc  # hashable: ``_case`` took only numbers and names
        out.append(sc)
    if not out:
        raise ValueError(f"{p}: no cases")
    return out


def _interned(value: _Pairs, seen: dict) -> _Pairs:
    try:
        return seen.setdefault(value, value)
    except TypeError:  # holds a list: not a valid case, refused with its field named
        return value


def _csv_row(p: Path, n: int, header: list[str], values: list[str]) -> dict:
    if len(values) > len(header):
        raise ValueError(f"{p}: case {n}: more values than the header names")
    return dict(zip(header, values))


def _case(p: Path, n: int, row: dict) -> Scenario:
    """Case ``n`` of file ``p`` from its fields, checked and built."""
    bad = [k for k, v in row.items() if isinstance(v, (bool, list, tuple, dict))]
    if bad:
        v = row[bad[0]]
        v = dict(v) if isinstance(v, _Pairs) else v
        raise ValueError(f"{p}: case {n}: {bad[0]}: expected a number or a name, got {v!r:.80}")
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
    except (ValueError, OverflowError) as err:
        raise ValueError(f"{p}: case {n}: {err}") from None
    return sc


def selected(args) -> list:
    """The cases (``--cases``/``--sample``) or layouts (``--layouts``) to run, filtered by
    ``--types``; repeats are reported and run once."""

    if getattr(args, "layouts", None):
        items, repeats = layouts_from(args.layouts, args.types, getattr(args, "vehicle", None))
        what = "--layouts"
    else:
        if getattr(args, "vehicle", None):
            raise ValueError("--vehicle: only with --layouts (the grid's cases are drawn for the paper's car)")
        items, repeats = cases_from(args.sample, args.cases, args.types)
        what = args.cases
    if repeats:
        print(f"mirrorpark: note: {what}: {repeats} repeated case(s) run once", file=sys.stderr)
    return chunk(items, getattr(args, "chunk", None))
