"""Layouts: files (native and TPCAP), exact decomposition, collisions, the env and the planners."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from shapely.geometry import Point, Polygon
from shapely.ops import unary_union

import mirrorpark_env  # noqa: F401
from evaluation.cases import from_sample
from evaluation.registry import make_policy
from mirrorpark_env.decompose import convex_parts
from mirrorpark_env.layout import Layout, Slot
from mirrorpark_env.layout_io import load_layout, load_layouts, write_layout
from mirrorpark_env.scenario import Scenario, grid_layout
from mirrorpark_env.vehicle import VehicleParams, footprint
from planners.base import run_episode

P = VehicleParams.table_ii()
TPCAP = Path(__file__).resolve().parent.parent / "configs" / "layouts" / "tpcap"
L_SHAPE = [(0.0, 0.0), (4.0, 0.0), (4.0, 1.0), (1.0, 1.0), (1.0, 3.0), (0.0, 3.0)]
U_SHAPE = [(0.0, 0.0), (3.0, 0.0), (3.0, 2.0), (2.5, 2.0), (2.5, 0.5), (0.5, 0.5), (0.5, 2.0), (0.0, 2.0)]


def _row(start, target, polys) -> str:
    vals = [*start, *target, len(polys), *(len(p) for p in polys), *(v for p in polys for xy in p for v in xy)]
    return ",".join(repr(float(v)) if not isinstance(v, int) else str(v) for v in vals) + "\n"


# ------------------------------------------------------------------ decomposition
@pytest.mark.parametrize("shape", [L_SHAPE, U_SHAPE, [(0, 0), (2, 0), (2, 2), (0, 2)]])
def test_convex_parts_cover_the_polygon_exactly(shape):
    poly = Polygon(shape)
    parts = convex_parts(np.array(shape, float))
    polys = [Polygon(q) for q in parts]
    assert all(abs(q.area - q.convex_hull.area) < 1e-12 for q in polys)  # each part convex
    assert sum(q.area for q in polys) == pytest.approx(poly.area, abs=1e-12)  # no overlap
    assert unary_union(polys).symmetric_difference(poly).area < 1e-12  # nothing missing
    rng = np.random.default_rng(0)
    for x, y in rng.uniform(-0.5, 4.5, size=(400, 2)):
        pt = Point(x, y)
        if poly.exterior.distance(pt) < 1e-9:
            continue
        assert poly.contains(pt) == any(q.contains(pt) or q.boundary.distance(pt) < 1e-12 for q in polys)


def test_a_self_intersecting_polygon_is_rejected():
    with pytest.raises(ValueError, match="not a simple polygon"):
        convex_parts(np.array([(0, 0), (2, 2), (2, 0), (0, 2)], float))


# ------------------------------------------------------------------ TPCAP reader
def test_tpcap_row_far_away_with_headings_beyond_pi_and_a_non_convex_obstacle(tmp_path):
    ox, oy = 3512.3, -1820.7
    start = (ox - 6.0, oy + 2.0, 2 * math.pi + 0.1)  # heading beyond pi
    target = (ox + 0.5, oy - 1.0, -4 * math.pi)  # = 0
    wall = [(ox - 10 + x, oy - 3 + y) for x, y in L_SHAPE]
    car = [(ox + 4, oy - 2), (ox + 8, oy - 2), (ox + 8, oy), (ox + 4, oy)]
    f = tmp_path / "far.csv"
    f.write_text(_row(start, target, [wall, car]))
    lay = load_layout(f, P)  # drawn for the paper's car (TPCAP's, the default, would overlap the wall)
    assert lay.name == "far"
    assert lay.origin == (3513.0, -1822.0)  # the target rounded to whole metres: shifts are exact
    assert lay.start[2] == pytest.approx(0.1, abs=1e-12)
    assert lay.target[2] == pytest.approx(0.0, abs=1e-12)
    assert lay.start[0] == pytest.approx(start[0] - 3513.0, abs=1e-9)
    assert np.allclose(lay.obstacles[0], np.array(wall) - (3513.0, -1822.0), atol=1e-9)
    parts = lay.parts[0]
    assert len(parts) == 2  # the L cut into two convex parts
    assert sum(Polygon(q).area for q in parts) == pytest.approx(Polygon(L_SHAPE).area, abs=1e-9)
    g = lay.build()
    assert len(g.obstacles) == 3


def test_a_tpcap_file_of_several_rows_names_each(tmp_path):
    f = tmp_path / "two.csv"
    row = _row((0, 0, 0), (10, 0, 0), [[(3, 3), (4, 3), (4, 4), (3, 4)]])
    f.write_text(row + row)
    assert [lay.name for lay in load_layouts(f)] == ["two#1", "two#2"]
    assert load_layout(f"{f}#2").name == "two#2"
    with pytest.raises(ValueError, match="holds 2 layouts"):
        load_layout(f)


def test_slot_inferred_from_parked_cars_and_a_kerb(tmp_path):
    # A parallel slot: cars end at x = -0.1 and start at x = 6.1, a kerb from y = -2.2 down.
    tx = 3.0 - P.center_offset  # rear axle of a car centred at x = 3.0, y = -1.1
    f = tmp_path / "par.csv"
    polys = [[(-5, -2), (-0.1, -2), (-0.1, -0.2), (-5, -0.2)], [(6.1, -2), (11, -2), (11, -0.2), (6.1, -0.2)]]
    polys.append([(-8, -3), (14, -3), (14, -2.2), (-8, -2.2)])
    f.write_text(_row((9.0, 1.5, 0.0), (tx, -1.1, 0.0), polys))
    s = load_layout(f, P).slot  # the paper's car: TPCAP's is 4.69 m long
    assert s.parking_type.value == "parallel"
    # Centred on the car: ends 3.0 - 0.1 = 2.9 m either side; across, the kerb gap both ways.
    assert s.length == pytest.approx(2 * 3.1, abs=1e-9)
    assert s.width == pytest.approx(P.width + 2 * (2.2 - 1.1 - 0.5 * P.width), abs=1e-9)


# ------------------------------------------------------------------ bad files
@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0,0,0,5,0,0,1,4,1,1,2,1,2,2,1\n", r"bad\.csv: row 1: the vertex counts \[4\] need 8 coordinates, got 7"),
        ("0,0,0,5,0,0,1.5,4\n", r"row 1: m \(the number of obstacles, value 7\) must be a whole number"),
        ("0,0,0,5,x,0,0\n", r"row 1: not a number: 'x'"),
        ("0,0,0,5,0,0,1,2,1,1,2,2\n", r"row 1: n_1 \(vertices of obstacle 1\) must be a whole number >= 3"),
        ("0,0,0\n", r"row 1: expected at least 7 values"),
    ],
)
def test_a_malformed_tpcap_row_is_rejected_naming_file_row_and_problem(tmp_path, text, message):
    f = tmp_path / "bad.csv"
    f.write_text("0,0,0,10,0,0,0\n" + text if "row 1" not in message else text)
    with pytest.raises(ValueError, match=message):
        load_layouts(f)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("start: {x: 0, y: 0, heading_deg: 0}\n", r"bad\.yaml: target: Field required"),
        (
            "start: {x: 0, y: 0, heading_deg: 0}\ntarget: {x: 9, y: 0, heading_deg: 0, heading: 0}\n",
            r"target: .*exactly one",
        ),
        (
            "start: {x: 0, y: 0, heading_deg: 0}\ntarget: {x: 9, y: 0, heading_deg: 0}\n"
            "slot: {corners: [[0, 0], [5, 0], [5, 2], [0, 2]], type: diagonal}\n",
            r"slot\.SlotModel\.type",
        ),
        (
            "start: {x: 0, y: 0, heading_deg: 0}\ntarget: {x: 9, y: 0, heading_deg: 0}\n"
            "slot: {corners: [[0, 0], [5, 0], [5, 2], [0, 3]], type: parallel}\n",
            r"bad\.yaml: slot\.corners: not a rectangle",
        ),
        (
            "start: {x: 0, y: 0, heading_deg: 0}\ntarget: {x: 9, y: 0, heading_deg: 0}\n"
            "obstacles: [[[0, 0], [2, 2], [2, 0], [0, 2]]]\n",
            r"bad\.yaml: obstacles\[0\]: not a simple polygon",
        ),
        ("start: {x: .nan, y: 0, heading_deg: 0}\ntarget: {x: 9, y: 0, heading_deg: 0}\n", r"start\.x"),
    ],
)
def test_a_malformed_native_layout_is_rejected_naming_the_field(tmp_path, text, message):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_layouts(f)


def test_a_start_inside_an_obstacle_is_rejected():
    lay = Layout(obstacles=([(-1, -1), (1, -1), (1, 1), (-1, 1)],), start=(0, 0, 0), target=(10, 0, 0), name="x")
    with pytest.raises(ValueError, match="x: start: the car at .* overlaps obstacle part 0"):
        lay.build()


# ------------------------------------------------------------------ collisions
def test_collisions_in_a_layout_agree_with_shapely_on_random_poses():
    obstacles = (np.array(L_SHAPE) + (2, 1), np.array(U_SHAPE) + (-5, -4), [(6, -3), (8, -3), (7, -1)])
    boundary = [(-9, -8), (12, -8), (12, 6), (3, 6), (3, 9), (-9, 9)]  # non-convex drivable area
    lay = Layout(obstacles=obstacles, start=(-6, 4, 0), target=(8, 3, 0), boundary=boundary, name="clutter")
    g = lay.build()
    inner = Polygon(boundary)  # the wall outside it: its box 3 m out (layout.BOUNDARY_DEPTH), less the area
    wall = inner.buffer(3.0, join_style="mitre").envelope.difference(inner)
    world = unary_union([Polygon(p) for p in obstacles] + [wall])
    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.uniform(-12, 15, 3000), rng.uniform(-11, 12, 3000), rng.uniform(-np.pi, np.pi, 3000)])
    hit = g.checker.collides(poses[:, 0], poses[:, 1], poses[:, 2])
    checked = 0
    for (x, y, th), h in zip(poses, hit):
        car = Polygon(footprint(P, x, y, th))
        area = car.intersection(world).area
        if area > 1e-6:
            assert h, (x, y, th, area)
        elif car.distance(world) > 1e-6:
            assert not h, (x, y, th)
        else:
            continue  # touching within a micrometre: either verdict is exact to rounding
        checked += 1
    assert checked > 2900 and 200 < hit.sum() < 2800


# ------------------------------------------------------------------ the environment
def _episode(env, policy, spec):
    trace: list[dict] = []
    info, _ = run_episode(env, policy, spec, trace=trace)
    path = np.array([(i["vehicle_state"].x, i["vehicle_state"].y, i["vehicle_state"].theta) for i in trace])
    return info, path


FIXED = ("parallel_rw5.00_sl6.50_sw2.50_th+0_y2.00", "reverse_rw6.00_sl4.82_sw2.37_th+20_y3.00")


@pytest.mark.parametrize(
    ("planner", "cases"),
    [
        ("mirror", [sc.case_id for sc in from_sample("smoke")[::10]]),  # 9 cases, every type, parked or not
        ("hybrid-astar", [*FIXED, "angle_rw5.50_sl4.82_sw2.17_th-10_y2.50"]),
    ],
)
def test_a_grid_case_read_back_as_a_layout_gives_the_same_episode(tmp_path, planner, cases):
    env = gym.make("MirrorPark-v0")
    for cid in cases:
        sc = Scenario.from_case_id(cid)
        f = write_layout(grid_layout(sc, P), tmp_path / f"{cid}.json")
        a, pa = _episode(env, make_policy(planner), sc)
        b, pb = _episode(env, make_policy(planner), load_layout(f))
        assert a["is_success"] == b["is_success"]
        assert a["failed_criterion"] == b["failed_criterion"]
        assert a["margins"] == b["margins"]
        assert (a["direction_switches"], a["parking_time"], a["path_length"]) == (
            b["direction_switches"],
            b["parking_time"],
            b["path_length"],
        )
        assert np.array_equal(pa, pb)


def test_the_mirror_planner_parks_a_turned_and_mirrored_layout_as_the_grid_case():
    sc = Scenario.from_case_id("reverse_rw6.00_sl4.82_sw2.37_th+20_y3.00")
    base = grid_layout(sc, P)
    ang, shift = 2.2, np.array([-40.0, 25.0])
    c, s = math.cos(ang), math.sin(ang)

    def move(p):  # reflect x -> -x, turn, shift
        q = np.asarray(p, float) * (-1.0, 1.0)
        return q @ np.array([[c, s], [-s, c]]) + shift

    def pose(q):
        x, y = move(q[:2])
        return (float(x), float(y), math.pi - q[2] + ang)

    moved = Layout(
        obstacles=tuple(move(p) for p in base.obstacles),
        start=pose(base.start),
        target=pose(base.target),
        slot=Slot(move(base.slot.corners), "reverse", base.slot.entrance),
        name="moved",
    )
    env = gym.make("MirrorPark-v0")
    a, _ = _episode(env, make_policy("mirror"), sc)
    b, _ = _episode(env, make_policy("mirror"), moved)
    assert a["is_success"] and b["is_success"]
    assert a["direction_switches"] == b["direction_switches"]
    assert b["path_length"] == pytest.approx(a["path_length"], abs=0.05)


def test_without_a_slot_both_planners_park_at_the_target_pose():
    """Hybrid A* plans to the pose; the mirror planner in a slot it draws there."""
    lay = Layout(
        obstacles=([(4, -3), (6, -3), (6, -1), (4, -1)], L_SHAPE),
        start=(-6.0, 0.0, 0.0),
        target=(12.0, 1.0, 0.3),
        name="open_lot",
    )
    env = gym.make("MirrorPark-v0")
    for planner in ("mirror", "hybrid-astar"):
        info, _ = _episode(env, make_policy(planner), lay)
        assert info["is_success"] and not info["collision"], planner
        assert 0.0 <= info["margins"]["M_pos"] <= 0.15


def test_a_target_boxed_in_but_behind_gets_no_slot_from_the_mirror_planner():
    """Walls left, right and ahead within 1 m: no side but the rear to come in by."""
    walls = [[(-2, 0.9), (6, 0.9), (6, 1.5), (-2, 1.5)], [(-2, -1.5), (6, -1.5), (6, -0.9), (-2, -0.9)]]
    walls.append([(3.5, -1.5), (4.2, -1.5), (4.2, 1.5), (3.5, 1.5)])
    lay = Layout(obstacles=walls, start=(-8.0, 0.0, 0.0), target=(0.0, 0.0, 0.0), name="boxed")
    env = gym.make("MirrorPark-v0")
    mirror = make_policy("mirror")
    info, _ = _episode(env, mirror, lay)
    assert mirror.status == "no_slot" and mirror.gave_up and not info["is_success"] and info["stopped"]


def test_lidar_reads_the_distance_to_a_wall():
    env = gym.make("MirrorPark-v0", config={"lidar": {"rays": 8, "max_range": 10.0}})
    lay = Layout(obstacles=([(10, -5), (11, -5), (11, 5), (10, 5)],), start=(0, 0, 0), target=(-5, 0, 0), name="w")
    obs, _ = env.reset(options={"layout": lay})
    centre = P.center_offset  # rays leave the body centre
    assert obs["lidar"][0] == pytest.approx((10 - centre) / 10.0, abs=1e-6)  # straight ahead
    assert obs["lidar"][4] == pytest.approx(1.0)  # behind: nothing within 10 m
    assert env.observation_space.contains(obs)


def test_a_layout_renders():
    env = gym.make("MirrorPark-v0", render_mode="rgb_array")
    env.reset(options={"layout": TPCAP / "per03.csv"})
    frame = env.render()
    assert frame.ndim == 3 and frame.std() > 0


# ------------------------------------------------------------------ the 20 TPCAP-format layouts
def test_the_tpcap_layouts_hold_what_they_claim():
    layouts = load_layouts(TPCAP)
    assert len(layouts) == 20
    assert sum(lay.origin != (0.0, 0.0) for lay in layouts) == 2  # far from the origin
    assert sum(any(len(parts) > 1 for parts in lay.parts) for lay in layouts) == 3  # non-convex obstacles
    raw_headings = [abs(float(v)) for f in TPCAP.glob("*.csv") for v in f.read_text().split(",")[2:6:3]]
    assert sum(h > math.pi for h in raw_headings) >= 5
    types = [lay.slot.parking_type.value for lay in layouts]
    assert {t: types.count(t) for t in set(types)} == {"parallel": 7, "reverse": 7, "angle": 6}


def test_mirror_parks_every_comfortable_tpcap_layout():
    env = gym.make("MirrorPark-v0")
    for lay in load_layouts(TPCAP):
        s, car = lay.slot, lay.vehicle  # TPCAP's car
        comfy = s.length >= 1.25 * car.length if s.parking_type.value == "parallel" else s.width >= car.width + 0.4
        if not comfy:
            continue
        info, _ = _episode(env, make_policy("mirror"), lay)
        assert info["is_success"] and not info["collision"], lay.name


def test_evaluate_layouts_writes_rows_paths_and_report_and_resumes(tmp_path):
    from evaluation.cli import main
    from evaluation.store import read_results

    folder = tmp_path / "lay"
    folder.mkdir()
    for name in ("per01.csv", "ang01.csv"):
        (folder / name).write_text((TPCAP / name).read_text())
    args = ["evaluate", "--planner", "mirror", "--layouts", str(folder), "--out", str(tmp_path / "r")]
    assert main([*args, "--workers", "1", "--quiet"]) == 0
    df = read_results([tmp_path / "r"])
    assert sorted(df["case_id"]) == ["ang01", "per01"] and df["success"].all()
    assert all(len(x) == len(y) > 10 for x, y in zip(df["path_x"], df["path_y"]))
    report = (tmp_path / "r" / "layouts.md").read_text()
    assert "| per01 | mirror | reverse |" in report and (tmp_path / "r" / "img" / "per01.png").exists()
    # The trajectory in TPCAP's four columns, in the file's frame: it starts at the file's start.
    traj = pd.read_csv(tmp_path / "r" / "trajectories" / "per01-mirror.csv")
    assert list(traj.columns) == ["t", "x", "y", "theta"] and traj["t"].iloc[0] == 0.0
    assert np.allclose(np.diff(traj["t"]), 0.1, atol=1e-6)
    x0, y0, th0 = (float(v) for v in (TPCAP / "per01.csv").read_text().split(",")[:3])
    assert (traj["x"].iloc[0], traj["y"].iloc[0]) == pytest.approx((x0, y0), abs=1e-4)
    assert math.cos(traj["theta"].iloc[0] - th0) == pytest.approx(1.0, abs=1e-9)
    assert main([*args, "--workers", "1", "--quiet"]) == 0  # resumes: nothing left to run
    again = read_results([tmp_path / "r"])
    assert len(again) == 2
    assert sorted(again["episode_wall_s"]) == sorted(df["episode_wall_s"])  # the same rows, not rerun


def test_the_example_layouts_load_as_documented():
    examples = {lay.name: lay for lay in load_layouts(TPCAP.parent / "examples")}
    assert set(examples) == {"open_lot", "garage_slot"}
    lot = examples["open_lot"]
    assert lot.slot is None and lot.boundary is not None and len(lot.parts[3]) == 2  # the planter, cut
    g = lot.build()
    assert g.checker.collides(0.0, 7.0, 0.0)[0]  # beyond the boundary's inner corner: the wall
    assert not g.checker.collides(2.0, 2.5, 0.0)[0]
    assert examples["garage_slot"].slot.parking_type.value == "reverse"
