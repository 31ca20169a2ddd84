"""Perturbations (``mirrorpark_env.perturb``): each has the statistics it claims, the truth is
never perturbed, episodes repeat, and bad settings are refused naming the field."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import mirrorpark_env  # noqa: F401  (registers MirrorPark-v0)
from mirrorpark_env import VehicleParams, to_action
from mirrorpark_env.config import NoiseConfig, PerturbConfig
from mirrorpark_env.criteria import SuccessCriteria
from mirrorpark_env.perturb import CommandPath, MeasurementNoise, late_box, truth_params
from mirrorpark_env.vehicle import footprint

P = VehicleParams.table_ii()
CASE = "parallel_rw4.50_sl6.00_sw2.50_th+0_y1.60"
DT = 0.1


def make(perturb=None, **extra):
    cfg = dict(extra) | ({} if perturb is None else {"perturb": perturb})
    return gym.make("MirrorPark-v0", config=cfg or None).unwrapped


def drive(env, commands, case=CASE):
    """Reset on ``case`` and apply the physical ``commands``; the infos of reset and each step."""
    obs, info = env.reset(options={"scenario": case})
    infos = [info]
    for a, d in commands:
        obs, _, term, _, info = env.step(to_action(P, a, d))
        infos.append(info)
        if term:
            break
    return infos


def test_white_noise_has_its_mean_and_deviation():
    cfg = NoiseConfig(position_std=0.1, heading_std_deg=0.5, speed_std=0.2, lateral_bias=0.05, speed_bias=-0.1)
    noise = MeasurementNoise(cfg, DT, np.random.default_rng(3))
    true = np.array([2.0, 1.0, 0.0, 0.5, 0.0, 0.0])  # heading 0: the car's frame is the world's
    m = np.array([[s.x, s.y, s.theta, s.v] for s in (noise.measure(true) for _ in range(40_000))]) - true[:4]
    assert m.mean(axis=0) == pytest.approx([0.0, 0.05, 0.0, -0.1], abs=0.004)
    assert m.std(axis=0) == pytest.approx([0.1, 0.1, math.radians(0.5), 0.2], rel=0.02)
    assert abs(np.corrcoef(m[:-1, 0], m[1:, 0])[0, 1]) < 0.02  # independent per step


def test_correlated_noise_keeps_its_deviation_and_correlates_as_claimed():
    noise = MeasurementNoise(NoiseConfig(position_std=0.1, correlation_time_s=1.0), DT, np.random.default_rng(4))
    true = np.zeros(6)
    e = np.array([noise.measure(true).x for _ in range(60_000)])
    assert e.std() == pytest.approx(0.1, rel=0.05)
    assert np.corrcoef(e[:-1], e[1:])[0, 1] == pytest.approx(math.exp(-DT / 1.0), abs=0.01)


def test_position_bias_is_in_the_cars_frame():
    noise = MeasurementNoise(NoiseConfig(longitudinal_bias=0.3), DT, np.random.default_rng(0))
    s = noise.measure(np.array([1.0, 2.0, math.pi / 2, 0.0, 0.0, 0.0]))  # facing +Y
    assert (s.x, s.y) == pytest.approx((1.0, 2.3))


def test_delay_shifts_the_commands_by_exactly_k_steps():
    cmds = [(1.0, 0.3)] * 6 + [(-2.0, -0.2)] * 6
    k = 3
    plain = [i["vehicle_state"] for i in drive(make(), [(0.0, 0.0)] * k + cmds)]
    late = [i["true_state"] for i in drive(make({"delay_steps": k}), cmds)]
    for a, b in zip(late, plain):
        assert a.as_array() == pytest.approx(b.as_array(), abs=1e-12)


def test_a_scaled_steering_lag_follows_its_closed_form():
    scale, cmd = 2.5, 0.3
    infos = drive(make({"actuator": {"tau_steer_scale": scale}}), [(0.0, cmd)] * 8)
    tau = P.tau_steer_s * scale
    for n, info in enumerate(infos):
        assert info["true_state"].delta == pytest.approx(cmd * (1 - math.exp(-n * DT / tau)), abs=1e-12)


def test_steering_gain_offset_and_rate_limit():
    path = CommandPath(PerturbConfig(actuator={"steer_gain": 0.9, "steer_offset_deg": 1.0}).actuator, 0, DT)
    assert path.apply(0.0, 0.4)[1] == pytest.approx(0.9 * 0.4 + math.radians(1.0))
    limited = CommandPath(PerturbConfig(actuator={"steer_rate_max_deg_s": 40, "jerk_max": 10}).actuator, 0, DT)
    steps = [limited.apply(3.0, 0.6) for _ in range(20)]
    d = np.diff([0.0] + [s[1] for s in steps])
    a = np.diff([0.0] + [s[0] for s in steps])
    assert d.max() == pytest.approx(math.radians(40) * DT) and steps[-1][1] == pytest.approx(0.6)
    assert a.max() == pytest.approx(10 * DT) and steps[-1][0] == pytest.approx(3.0)


def test_model_error_changes_the_truth_car_not_the_told_one():
    env = make({"model": {"front_length": 0.2, "width": 0.1, "max_steer_scale": 0.9}})
    _, info = env.reset(options={"scenario": CASE})
    assert info["geometry"].vehicle == P  # the planners are told of the paper's car
    truth = truth_params(P, env.cfg.perturb)
    assert env.geometry.vehicle == truth and truth.front_length == pytest.approx(P.front_length + 0.2)
    infos = drive(env, [(0.0, 0.6)] * 10)  # full lock commanded: the truth's wheels stop at 0.9 of it
    assert infos[-1]["true_state"].delta == pytest.approx(0.9 * P.max_steer_rad, abs=1e-3)


def test_zero_perturbation_gives_todays_episode_bit_for_bit():
    cmds = [(1.0, 0.2)] * 10 + [(-3.0, -0.4)] * 10
    a, b = drive(make(), cmds), drive(make({}), cmds)
    for x, y in zip(a, b):
        assert x["vehicle_state"] == y["vehicle_state"] == y["true_state"]
        assert (x["is_success"], x["collision"], x["min_clearance"]) == (
            y["is_success"],
            y["collision"],
            y["min_clearance"],
        )


def test_verdicts_stay_on_the_truth():
    """Under severe noise the collision and ISO verdicts of every step match an independent
    recomputation from the true states, with the truth car's footprint, not the measured ones."""
    env = make("severe")
    infos = drive(env, [(1.0, 0.6)] * 60)  # a left turn into the far road boundary
    layout = infos[0]["layout"]
    truth = layout.build(truth_params(P, env.cfg.perturb))
    crit = SuccessCriteria(truth, env.cfg.criteria)
    hit = False
    for i, info in enumerate(infos):
        s, m = info["true_state"], info["vehicle_state"]
        assert i == 0 or (s.x, s.y) != (m.x, m.y)  # the planners saw something else
        hit = hit or bool(truth.checker.penetration(s.x, s.y, s.theta)[0].max() > 1e-9)
        assert info["collision"] == hit
        v = crit.verdict(s.x, s.y, s.theta, s.v, info["parking_time"], hit)
        assert (info["is_success"], info["failed_criterion"]) == (v.success, v.failed)
    assert hit and infos[-1]["collision"]


def test_the_late_obstacle_is_seen_and_hits():
    env = make({"late_obstacle": {"time_s": 1.0, "ahead": 2.0}}, lidar={"rays": 72, "max_range": 10.0})
    obs, info = env.reset(options={"scenario": "reverse_rw6.00_sl5.50_sw2.80_th+0_y2.00"})
    n0 = len(info["geometry"].obstacles.polygons)
    ahead0 = obs["lidar"][0]  # ray 0 looks along the car's heading
    seen = None
    for k in range(200):
        obs, _, term, _, info = env.step(to_action(P, 0.5 if k < 30 else 0.0, 0.0))
        if "geometry" in info:
            seen = (k, info["geometry"], obs["lidar"][0])
        if term:
            break
    k, g, ahead = seen
    assert (k + 1) * DT == pytest.approx(1.0) and len(g.obstacles.polygons) == n0 + 1
    assert ahead < ahead0 and ahead * 10.0 < 2.0 + P.front_length - P.center_offset + 0.3
    assert info["collision"] and info["failed_criterion"] == "collision"


def test_the_late_box_sits_beyond_the_bumper_it_drives_toward():
    cfg = PerturbConfig(late_obstacle={"time_s": 0.0, "ahead": 1.0}).late_obstacle
    fwd = late_box(cfg, P, 0.0, 0.0, 0.0, 1)
    back = late_box(cfg, P, 0.0, 0.0, 0.0, -1)
    assert fwd[:, 0].min() == pytest.approx(P.front_length + 1.0)
    assert back[:, 0].max() == pytest.approx(-P.rear_overhang - 1.0)
    car = footprint(P, 0.0, 0.0, 0.0)
    assert car[:, 0].max() < fwd[:, 0].min() and car[:, 0].min() > back[:, 0].max()


def test_same_case_seed_and_preset_repeat_and_seeds_differ():
    cmds = [(1.0, 0.2)] * 20
    runs = [[i["vehicle_state"] for i in drive(make("moderate"), cmds)] for _ in range(2)]
    assert runs[0] == runs[1]
    other = [i["vehicle_state"] for i in drive(make({"name": "m2", "seed": 7, "noise": {"position_std": 0.1}}), cmds)]
    assert other != runs[0]


@pytest.mark.parametrize(
    ("perturb", "named"),
    [
        ({"delay_steps": -1}, "perturb.delay_steps"),
        ({"noise": {"position_std": 5}}, "perturb.noise.position_std"),
        ({"actuator": {"steer_gain": 2}}, "perturb.actuator.steer_gain"),
        ({"model": {"wheelbase": 1}}, "perturb.model.wheelbase"),
        ({"late_obstacle": {"ahead": 1}}, "perturb.late_obstacle.time_s"),
        ({"bogus": 1}, "perturb.bogus"),
        ("extreme", "perturb: a preset in"),
    ],
)
def test_bad_perturbations_are_refused_naming_the_field(perturb, named):
    with pytest.raises(ValueError, match=named.replace(".", r"\.")):
        make(perturb)


_settings = st.fixed_dictionaries(
    {},
    optional={
        "noise": st.fixed_dictionaries(
            {},
            optional={
                "position_std": st.floats(0, 2),
                "heading_std_deg": st.floats(0, 20),
                "correlation_time_s": st.floats(0, 600),
            },
        ),
        "actuator": st.fixed_dictionaries(
            {},
            optional={
                "tau_steer_scale": st.floats(0.2, 10),
                "steer_gain": st.floats(0.5, 1.5),
                "steer_rate_max_deg_s": st.floats(0, 2000),
                "jerk_max": st.floats(0, 1000),
            },
        ),
        "delay_steps": st.integers(0, 20),
        "model": st.fixed_dictionaries(
            {}, optional={"front_length": st.floats(-0.5, 0.5), "max_steer_scale": st.floats(0.7, 1.2)}
        ),
    },
)


@given(_settings, st.integers(0, 2**31 - 1))
def test_any_valid_perturbation_runs_and_keeps_the_truth_finite(settings, seed):
    env = make(settings | {"seed": seed})
    for info in drive(env, [(1.0, 0.3)] * 5):
        assert np.all(np.isfinite(info["true_state"].as_array()))
        assert np.all(np.isfinite(info["vehicle_state"].as_array()))
