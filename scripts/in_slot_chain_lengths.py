"""How many arcs the in-slot multi-point turns from the target reach, per parking type, over
every distinct slot of the full grid that admits an ISO pose.

Used to decide which full-grid chunks a change of ``GuideConfig.in_slot_arcs`` touches:
where no chain reaches the old limit, the guide's tails, and so the rows, are unchanged.
Run: ``python scripts/in_slot_chain_lengths.py [ARCS=12]``.
"""

from __future__ import annotations

import sys

from evaluation.cases import from_sample
from mirrorpark_env.criteria import iso_pose_exists
from planners.mirror.guide import GuideSearch


def main(arcs: int = 12) -> None:
    slots = {}
    for sc in from_sample("full"):
        slots.setdefault((sc.parking_type.value, sc.road_width, sc.slot_length, sc.slot_width), sc)
    longest: dict[str, int] = {}
    for (ptype, _, sl, sw), sc in slots.items():
        g = sc.build()
        if not iso_pose_exists(ptype, sl, sw, g.vehicle):
            continue
        search = GuideSearch(g)
        n = max((len(ends) for _, ends in search._turn_chains(search.target, None, arcs)), default=0)
        longest[ptype] = max(longest.get(ptype, 0), n)
    print(f"{len(slots)} distinct slots; longest in-slot chain (arcs, limit {arcs}): {longest}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 12)
