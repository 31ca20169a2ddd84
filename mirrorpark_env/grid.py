"""The paper's Table III scenario grid, with stable case ids, filters and samples.

A case "can be generated" when all four corners of the start footprint lie in the road
strip 0 <= Y <= RW (docs/design.md). That rule gives 12,420 parallel, 46,629
reverse and 11,385 angle cases (70,434 in all); the paper reports 12,995 parallel cases
(71,009 in all) from a placement rule it does not state. See docs/scenarios.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from .config import GridConfig, default_grid
from .criteria import iso_pose_exists
from .scenario import ParkingType, Scenario, slot_fits_car, start_fits_road
from .vehicle import VehicleParams

TYPES = tuple(ParkingType)
FACTORS = ("road_width", "slot_length", "slot_width", "theta0_deg", "y0")


@dataclass(frozen=True, eq=False)
class Grid:
    """All generable cases of a grid config, held as numpy columns."""

    config: GridConfig
    vehicle: VehicleParams
    columns: dict[str, np.ndarray]  # "type" (int index into TYPES), FACTORS, "feasible" (an ISO pose exists)

    @classmethod
    def from_config(cls, config: GridConfig | None = None, vehicle: VehicleParams | None = None) -> Grid:
        config = config or default_grid()
        vehicle = vehicle or VehicleParams.table_ii()
        cols: dict[str, list[np.ndarray]] = {k: [] for k in ("type", *FACTORS)}
        thetas = np.array(config.theta0_deg.values())
        for ti, t in enumerate(TYPES):
            tg = config.types.get(t.value)
            if tg is None:
                continue
            for rw in tg.road_widths:
                n_y = int(math.floor(rw / config.y0_step + 1e-9)) + 1
                ys = np.round(np.arange(n_y) * config.y0_step, 10)
                th, y = np.meshgrid(thetas, ys, indexing="ij")
                ok = start_fits_road(vehicle, np.radians(th), y, rw)
                th, y = th[ok], y[ok]
                for sl in tg.slot_length.values():
                    for sw in tg.slot_width.values():
                        if not slot_fits_car(vehicle, sl, sw):
                            continue  # too small for this car: not a case
                        n = len(th)
                        cols["type"].append(np.full(n, ti, dtype=np.int8))
                        cols["road_width"].append(np.full(n, rw))
                        cols["slot_length"].append(np.full(n, sl))
                        cols["slot_width"].append(np.full(n, sw))
                        cols["theta0_deg"].append(th)
                        cols["y0"].append(y)
        columns = {k: (np.concatenate(v) if v else np.empty(0)) for k, v in cols.items()}
        names = np.array([t.value for t in TYPES])[columns["type"].astype(int)]
        columns["feasible"] = iso_pose_exists(names, columns["slot_length"], columns["slot_width"], vehicle)
        return cls(config, vehicle, columns)

    def __len__(self) -> int:
        return len(self.columns["type"])

    def scenario(self, i: int) -> Scenario:
        c = self.columns
        return Scenario.from_degrees(
            TYPES[int(c["type"][i])],
            float(c["road_width"][i]),
            float(c["slot_length"][i]),
            float(c["slot_width"][i]),
            float(c["theta0_deg"][i]),
            float(c["y0"][i]),
            self.config.start_x_offset,
        )

    def __iter__(self) -> Iterator[Scenario]:
        return (self.scenario(i) for i in range(len(self)))

    def counts(self) -> dict:
        """Cases per parking type and in total, and under ``feasible`` those whose slot
        admits an ISO-compliant final pose (``criteria.iso_pose_exists``)."""
        types = self.columns["type"].astype(int)
        n = np.bincount(types, minlength=len(TYPES))
        f = np.bincount(types[self.columns["feasible"]], minlength=len(TYPES))
        out: dict = {t.value: int(n[i]) for i, t in enumerate(TYPES)}
        out["total"] = int(n.sum())
        out["feasible"] = {t.value: int(f[i]) for i, t in enumerate(TYPES)} | {"total": int(f.sum())}
        return out

    @cached_property
    def _id_index(self) -> dict[str, int]:
        return {self.scenario(i).case_id: i for i in range(len(self))}

    def case_ids(self) -> list[str]:
        return list(self._id_index)

    def by_id(self, case_id: str) -> Scenario:
        i = self._id_index.get(case_id)
        if i is None:
            raise KeyError(f"case id {case_id!r} is not in the grid")
        return self.scenario(i)

    def indices(self, parking_type: str | ParkingType | None = None, **factors) -> np.ndarray:
        """Indices of the cases matching a type and factor filters.

        A factor filter is a value (matched to 1e-6) or an inclusive ``(lo, hi)`` range,
        e.g. ``indices("parallel", road_width=4.5, y0=(1.6, 4.5))``.
        """
        mask = np.ones(len(self), dtype=bool)
        if parking_type is not None:
            ti = TYPES.index(ParkingType.parse(parking_type))
            mask &= self.columns["type"] == ti
        for name, want in factors.items():
            if name not in FACTORS:
                raise ValueError(f"filter: unknown factor {name!r}; allowed: {', '.join(FACTORS)}")
            col = self.columns[name]
            if isinstance(want, tuple | list):
                lo, hi = want
                mask &= (col >= lo - 1e-6) & (col <= hi + 1e-6)
            else:
                mask &= np.abs(col - float(want)) <= 1e-6
        return np.flatnonzero(mask)

    def filter(self, parking_type: str | ParkingType | None = None, **factors) -> list[Scenario]:
        return [self.scenario(i) for i in self.indices(parking_type, **factors)]

    def sample_indices(
        self, n_per_type: int | str, seed: int | None = None, types: tuple[str, ...] | None = None
    ) -> np.ndarray:
        """A stratified, seeded sample: ``n_per_type`` cases of each parking type.

        Strata are road width x slot-size tercile, so every road width and narrow, middle
        and wide slots are represented evenly; within a stratum cases are drawn uniformly
        without replacement. ``n_per_type`` may name a sample of the config (``smoke``,
        ``standard``); ``full`` is the whole grid.
        """
        if isinstance(n_per_type, str):
            if n_per_type == "full":
                return np.arange(len(self))
            if n_per_type not in self.config.samples:
                allowed = ", ".join([*self.config.samples, "full"])
                raise ValueError(f"sample: unknown {n_per_type!r}; allowed: {allowed}")
            n_per_type = self.config.samples[n_per_type]
        if n_per_type < 1:
            raise ValueError(f"sample: n_per_type must be >= 1, got {n_per_type}")
        seed = self.config.seed if seed is None else seed
        chosen = []
        for ti, t in enumerate(TYPES):
            if types is not None and t.value not in types:
                continue
            idx = self.indices(t)
            if len(idx) == 0:
                continue
            chosen.append(self._stratified(idx, n_per_type, np.random.default_rng([seed, ti])))
        return np.sort(np.concatenate(chosen)) if chosen else np.empty(0, dtype=int)

    def _stratified(self, idx: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
        c = self.columns
        size = c["slot_length"][idx] * c["slot_width"][idx]
        levels = np.unique(size)
        tercile = np.minimum((np.searchsorted(levels, size) * 3) // len(levels), 2)
        key = np.unique(c["road_width"][idx], return_inverse=True)[1] * 3 + tercile
        strata = [idx[key == k] for k in np.unique(key)]
        n = min(n, len(idx))
        quota = np.zeros(len(strata), dtype=int)
        left = n
        order = rng.permutation(len(strata))
        while left > 0:  # round-robin so strata that run out pass their share on
            for s in order:
                if left and quota[s] < len(strata[s]):
                    quota[s] += 1
                    left -= 1
        return np.concatenate([rng.choice(s, q, replace=False) for s, q in zip(strata, quota) if q])

    def sample(
        self, n_per_type: int | str, seed: int | None = None, types: tuple[str, ...] | None = None
    ) -> list[Scenario]:
        return [self.scenario(i) for i in self.sample_indices(n_per_type, seed, types)]


_DEFAULT: Grid | None = None


def default_grid_cases() -> Grid:
    """The shipped Table III grid (built once per process)."""
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = Grid.from_config()
    return _DEFAULT


@lru_cache(maxsize=8)
def grid_for(vehicle: VehicleParams) -> Grid:
    """The shipped Table III grid's cases that can be generated for ``vehicle``."""
    if vehicle == VehicleParams.table_ii():
        return default_grid_cases()
    return Grid.from_config(default_grid(), vehicle)
