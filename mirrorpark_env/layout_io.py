"""Layout files: MirrorPark's own YAML/JSON format and TPCAP's CSV rows.

Native format (docs/layouts.md), one layout per file; angles in degrees at this edge::

    name: corner_lot                # optional: the file's stem
    start: {x: 2.0, y: 3.0, heading_deg: 0}      # rear axle; or heading: RADIANS
    target: {x: 8.1, y: -1.2, heading_deg: 0}
    obstacles: [[[0, 0], [5, 0], [5, -2], [0, -2]], ...]   # polygons, convex or not
    boundary: [[-10, -5], [30, -5], [30, 10], [-10, 10]]   # optional drivable area
    slot:                           # optional; "infer" reads it off the obstacles
      corners: [[x, y], [x, y], [x, y], [x, y]]   # a rectangle
      type: parallel                # parallel | reverse | angle
      entrance: 0                   # the entrance edge runs from corners[i] to corners[i + 1]
      road_heading_deg: 0           # optional: direction of travel past the slot
    bounds: [x_min, x_max, y_min, y_max]   # optional scene box
    road_width: 6.0                 # optional
    vehicle: paper                  # optional: paper | tpcap | a YAML file of vehicle fields | the fields

TPCAP (the trajectory-planning competition for automated parking) writes one case per row,
read as is: ``x0, y0, theta0, xf, yf, thetaf, m, n_1 ... n_m`` then the m polygons'
vertices as x, y pairs; headings in radians (any value: wrapped), coordinates anywhere
(recentred when far from the origin), polygons convex or not. Its car is TPCAP's
(``vehicle.vehicle_named("tpcap")``) and the slot is inferred (``slot_inference``) in the
recentred frame. A file may hold several rows: layout ``STEM`` for one, else
``STEM#1``, ``STEM#2``, ... Every error names the file, the row or field and the problem.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from .config import StrictModel, VehicleConfig, validate
from .layout import NAME_MAX, Layout, Slot
from .slot_inference import infer_slot
from .textfile import csv_rows, parse_json, parse_yaml, read_text
from .vehicle import VEHICLES, VehicleParams, vehicle_name, vehicle_named

SUFFIXES = (".yaml", ".yml", ".json", ".csv")

Point = tuple[float, float]


class PoseModel(StrictModel):
    x: float = Field(allow_inf_nan=False)
    y: float = Field(allow_inf_nan=False)
    heading_deg: float | None = Field(None, allow_inf_nan=False)
    heading: float | None = Field(None, allow_inf_nan=False)  # [rad], instead of heading_deg

    @model_validator(mode="after")
    def _one_heading(self) -> PoseModel:
        if (self.heading is None) == (self.heading_deg is None):
            raise ValueError("give the heading as heading_deg (degrees) or heading (radians), exactly one")
        return self

    def radians(self) -> float:
        return self.heading if self.heading is not None else math.radians(self.heading_deg)


class SlotModel(StrictModel):
    corners: list[Point] = Field(min_length=4, max_length=4)
    type: Literal["parallel", "reverse", "angle"]
    entrance: int = Field(0, ge=0, le=3)
    road_heading_deg: float | None = Field(None, allow_inf_nan=False)


class LayoutModel(StrictModel):
    name: str | None = Field(None, min_length=1, max_length=NAME_MAX)
    start: PoseModel
    target: PoseModel
    obstacles: list[list[Point]] = Field(default_factory=list)
    boundary: list[Point] | None = None
    slot: SlotModel | Literal["infer"] | None = None
    bounds: tuple[float, float, float, float] | None = None
    road_width: float = Field(0.0, ge=0, le=100)
    vehicle: str | VehicleConfig | None = None  # paper | tpcap | FILE (beside the layout) | the fields


def _pose(p: PoseModel) -> tuple[float, float, float]:
    return (p.x, p.y, p.radians())


def vehicle_of(spec: str | VehicleConfig | None, folder: Path | None = None) -> VehicleParams | None:
    """A layout's car: a name, a YAML file (relative to ``folder``), the fields, or None."""
    if spec is None:
        return None
    if isinstance(spec, VehicleConfig):
        return VehicleParams.from_config(spec)
    if spec in VEHICLES or folder is None or Path(spec).is_absolute():
        return vehicle_named(spec)
    return vehicle_named(str(folder / spec))


def from_model(m: LayoutModel, name: str, folder: Path | None = None, vehicle: VehicleParams | None = None) -> Layout:
    """A validated native record as a ``Layout`` (recentred when far from the origin, its
    slot inferred there where it says ``infer``); ``vehicle`` overrides the record's car."""
    start, target = _pose(m.start), _pose(m.target)
    slot = None
    if isinstance(m.slot, SlotModel):
        rh = None if m.slot.road_heading_deg is None else math.radians(m.slot.road_heading_deg)
        slot = Slot(m.slot.corners, m.slot.type, m.slot.entrance, rh)
    layout = Layout(
        obstacles=tuple(m.obstacles),  # a bad polygon is named when it is cut into parts, below
        start=start,
        target=target,
        slot=slot,
        boundary=m.boundary,
        name=m.name or name,
        bounds=m.bounds,
        road_width=m.road_width,
        vehicle=vehicle or vehicle_of(m.vehicle, folder),
    )
    layout = layout.recentred()
    if m.slot == "infer":
        layout = with_inferred_slot(layout)
    layout.check()  # at load, named: a bad polygon, a start no car can take
    return layout


def with_inferred_slot(layout: Layout) -> Layout:
    """``layout`` with the slot read off its obstacles around the target for its car (none
    where none fits: the target pose is then the goal)."""
    from dataclasses import replace

    slot, _ = infer_slot(layout.obstacles, layout.start, layout.target, layout.vehicle)
    return replace(layout, slot=slot)


def to_dict(layout: Layout) -> dict:
    """The native record of ``layout`` (in its own frame; the inverse of ``from_model``)."""

    def pose(p):  # radians: a written layout reads back bit for bit
        return {"x": p[0], "y": p[1], "heading": p[2]}

    d: dict = {
        "name": layout.name,
        "start": pose(layout.start),
        "target": pose(layout.target),
        "obstacles": [p.tolist() for p in layout.obstacles],
    }
    if layout.boundary is not None:
        d["boundary"] = layout.boundary.tolist()
    if layout.slot is not None:
        s = layout.slot
        d["slot"] = {"corners": s.corners.tolist(), "type": s.parking_type.value, "entrance": s.entrance}
        if s.road_heading is not None:
            d["slot"]["road_heading_deg"] = math.degrees(s.road_heading)
    if layout.bounds is not None:
        d["bounds"] = list(layout.bounds)
    if layout.road_width:
        d["road_width"] = layout.road_width
    if layout.vehicle is not None:
        d["vehicle"] = vehicle_name(layout.vehicle) or layout.vehicle.as_config()
    return d


def content_key(layout: Layout) -> str:
    """A short hash of everything a layout's episode depends on (name, obstacles, boundary,
    start, target, slot, bounds, road width, frame origin and car): the key of its result
    rows beside its name, so that an edited file is run again, not answered from a row of
    its old content."""
    d = to_dict(layout)
    d["vehicle"] = None if layout.vehicle is None else layout.vehicle.as_config()
    d["origin"] = [float(v) for v in layout.origin]
    text = json.dumps(d, sort_keys=True, default=float, allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def write_layout(layout: Layout, path: str | Path) -> Path:
    """Write ``layout`` in the native format (JSON or YAML by the suffix)."""
    p = Path(path)
    d = to_dict(layout)
    if p.suffix.lower() == ".json":
        p.write_text(json.dumps(d, indent=1) + "\n")
    elif p.suffix.lower() in (".yaml", ".yml"):
        import yaml

        p.write_text(yaml.safe_dump(d, sort_keys=False))
    else:
        raise ValueError(f"{p}: a native layout file ends in .json, .yaml or .yml")
    return p


def _native(p: Path, vehicle: VehicleParams | None = None) -> list[Layout]:
    text = read_text(p, "layout file")
    data = parse_json(text, p) if p.suffix.lower() == ".json" else parse_yaml(text, p)
    m = validate(LayoutModel, data, source=str(p))
    try:
        return [from_model(m, p.stem, p.parent, vehicle)]
    except ValueError as err:
        raise ValueError(f"{p}: {err}") from None


def parse_tpcap_row(values: list[str]) -> tuple[tuple, tuple, list[list[Point]]]:
    """(start, target, polygons) of one TPCAP row; ``ValueError`` says what is wrong."""
    vals = [v.strip() for v in values if v.strip() != ""]
    if len(vals) < 7:
        raise ValueError(f"expected at least 7 values (x0, y0, theta0, xf, yf, thetaf, m), got {len(vals)}")
    try:
        nums = [float(v) for v in vals]
    except ValueError:
        bad = next(v for v in vals if not _is_float(v))
        raise ValueError(f"not a number: {bad!r}") from None
    if not all(math.isfinite(v) for v in nums):
        raise ValueError("values must be finite")
    start, target = tuple(nums[0:3]), tuple(nums[3:6])
    m = nums[6]
    if m != int(m) or m < 0:
        raise ValueError(f"m (the number of obstacles, value 7) must be a whole number >= 0, got {vals[6]}")
    m = int(m)
    if len(nums) < 7 + m:
        raise ValueError(f"m = {m} obstacles need {m} vertex counts after it, got {len(nums) - 7}")
    counts = nums[7 : 7 + m]
    for i, n in enumerate(counts):
        if n != int(n) or n < 3:
            raise ValueError(f"n_{i + 1} (vertices of obstacle {i + 1}) must be a whole number >= 3, got {n:g}")
    need = 2 * int(sum(counts))
    coords = nums[7 + m :]
    if len(coords) != need:
        raise ValueError(f"the vertex counts {[int(n) for n in counts]} need {need} coordinates, got {len(coords)}")
    polys, k = [], 0
    for n in counts:
        n = int(n)
        polys.append([(coords[k + 2 * j], coords[k + 2 * j + 1]) for j in range(n)])
        k += 2 * n
    return start, target, polys


def _is_float(v: str) -> bool:
    try:
        float(v)
    except ValueError:
        return False
    return True


def _tpcap(p: Path, vehicle: VehicleParams | None = None) -> list[Layout]:
    rows = [r for r in csv_rows(read_text(p, "layout file"), p) if any(c.strip() for c in r)]
    if not rows:
        raise ValueError(f"{p}: no rows")
    out = []
    for n, row in enumerate(rows, 1):
        name = p.stem if len(rows) == 1 else f"{p.stem}#{n}"
        try:
            start, target, polys = parse_tpcap_row(row)
            layout = Layout(tuple(polys), start, target, name=name, vehicle=vehicle or vehicle_named("tpcap"))
            layout = with_inferred_slot(layout.recentred())  # inferred in the recentred frame: exact there
            layout.check()  # at load, named: a bad polygon, a start no car can take
            out.append(layout)
        except ValueError as err:
            raise ValueError(f"{p}: row {n}: {err}") from None
    return out


def load_layouts(path: str | Path, vehicle: VehicleParams | None = None) -> list[Layout]:
    """Every layout in a file, or in the layout files of a folder (sorted by name). A folder
    with invalid files is refused whole, every invalid file named with its problem.
    ``vehicle``: the car of every layout, whatever its file says (TPCAP files: TPCAP's car;
    native files: their ``vehicle``, else the environment's)."""
    p = Path(path)
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in SUFFIXES)
        if not files:
            raise ValueError(f"{p}: no layout files ({', '.join(SUFFIXES)})")
        return load_many(files, vehicle)
    if not p.exists():
        raise ValueError(f"{p}: no such layout file or folder")
    suffix = p.suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"{p}: a layout file ends in {', '.join(SUFFIXES)}")
    return _tpcap(p, vehicle) if suffix == ".csv" else _native(p, vehicle)


def load_many(paths: list, vehicle: VehicleParams | None = None) -> list[Layout]:
    """The layouts of every file or folder in ``paths`` (``load_layouts``); any invalid ones
    refuse them all, each named with its problem, in one line."""
    out, errors = [], []
    for p in paths:
        try:
            out += load_layouts(p, vehicle)
        except ValueError as err:
            errors.append(str(err))
    if len(paths) == 1 and errors:
        raise ValueError(errors[0])
    if errors:
        raise ValueError(f"{len(errors)} of {len(paths)} layout files are invalid: " + "; ".join(errors))
    return out


def load_layout(path: str | Path, vehicle: VehicleParams | None = None) -> Layout:
    """The one layout in a file (a TPCAP file of several rows: name one with ``FILE#ROW``)."""
    s = str(path)
    row = None
    if "#" in Path(s).name:
        s, _, r = s.rpartition("#")
        if not r.isdigit() or int(r) < 1:
            raise ValueError(f"{path}: after '#' comes a row number >= 1")
        row = int(r)
    layouts = load_layouts(s, vehicle)
    if row is not None:
        if row > len(layouts):
            raise ValueError(f"{s}: has {len(layouts)} row(s), not {row}")
        return layouts[row - 1]
    if len(layouts) != 1:
        raise ValueError(f"{s}: holds {len(layouts)} layouts; name one as {s}#ROW")
    return layouts[0]
