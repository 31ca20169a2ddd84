"""Behaviour cloning from collected demonstrations (needs the rl extra)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from evaluation.collect import collect
from evaluation.registry import make_policy
from mirrorpark_env import Scenario

CASES = ["reverse_rw6.00_sl4.82_sw2.32_th+40_y3.00", "angle_rw3.50_sl4.82_sw2.77_th+10_y1.30"]


@pytest.mark.rl
def test_a_short_bc_run_lowers_the_action_error_on_its_dataset(tmp_path, require_module):
    require_module("stable_baselines3")
    require_module("minari")
    from evaluation.cli import main as cli
    from planners.rl.bc import action_error, load_demos
    from planners.rl.policy import load_model

    collect("guide-only", [Scenario.from_case_id(c) for c in CASES], tmp_path / "demos", workers=1, progress=False)
    out = tmp_path / "bc"
    argv = ["train-rl", "--demos", str(tmp_path / "demos"), "--epochs", "40", "--out", str(out)]
    assert cli(argv) == 0
    summary = json.loads((out / "train.json").read_text())
    assert summary["method"] == "bc" and summary["episodes"] == 2
    assert summary["action_error_after"] < 0.5 * summary["action_error_before"]
    obs, actions, _ = load_demos(tmp_path / "demos")
    model = load_model(str(out / "model.zip"))  # loads as any trained model (rl:PATH)
    assert action_error(model, obs, actions) == pytest.approx(summary["action_error_after"], rel=1e-4)
    assert np.isfinite(summary["loss_per_epoch"]).all()


@pytest.mark.rl
def test_a_dagger_round_labels_the_states_the_learner_visits(require_module):
    """The round's observations are the learner's own rollout, and each label is what the
    expert policy, riding along on exactly those states, answers."""
    require_module("stable_baselines3")
    import gymnasium as gym

    from planners.rl.dagger import ShadowExpert, rollouts

    class Learner:  # a fixed, simple learner: creep forward, wheels straight
        def predict(self, obs, deterministic=True):
            return np.array([0.3, 0.0], dtype=np.float32), None

    sc = Scenario.from_case_id(CASES[0])
    obs, labels, _, counts = rollouts(
        Learner(), ShadowExpert(make_policy("guide-only"), 20), [sc], beta=0.0, max_steps=12, seed=0
    )
    assert len(labels) == 12 and all(len(v) == 12 for v in obs.values()) and counts["episodes"] == 1
    # Replay the learner: the same states, and an expert riding along gives the same labels.
    env = gym.make("MirrorPark-v0")
    o, info = env.reset(options={"scenario": sc})
    expert = ShadowExpert(make_policy("guide-only"), 20)
    expert.reset(info["geometry"])
    for t in range(12):
        assert all(np.array_equal(obs[k][t], o[k]) for k in o)
        assert np.array_equal(labels[t], expert.label(o, info))
        o, *_, info = env.step(np.array([0.3, 0.0], dtype=np.float32))
    # The learner's creep is not what the expert does: the labels say so (it steers first).
    assert np.abs(labels - np.array([0.3, 0.0])).max() > 0.1


@pytest.mark.rl
def test_a_shielded_dagger_round_brakes_a_reckless_learner_and_labels_what_follows(require_module):
    """With ``dagger.shield`` the learner's actions pass the rl-shield filter: a learner that
    would hit the far kerb is braked short of it, the episode goes on, and the expert labels
    the states after the near-miss, which a collision would have cut off."""
    require_module("stable_baselines3")
    from planners.rl.dagger import ShadowExpert, rollouts

    class Reckless:  # full throttle, full left lock (tests/test_shield.py: it meets the far kerb)
        def predict(self, obs, deterministic=True):
            return np.array([1.0, 1.0], dtype=np.float32), None

    sc = Scenario.from_case_id("reverse_rw5.00_sl4.82_sw2.47_th+0_y2.00")
    run = lambda shield, second=False: rollouts(  # noqa: E731
        Reckless(), ShadowExpert(make_policy("guide-only"), 20), [sc], 0.0, 300, 0, shield=shield, second_gear=second
    )
    _, bare_labels, _, bare = run(False)
    obs, labels, _, shielded = run(True)
    assert bare["collided"] == 1 and bare["shielded_steps"] == 0
    assert shielded["collided"] == 0 and shielded["shielded_steps"] > 0 and shielded["gear_swaps"] == 0
    assert len(labels) > len(bare_labels)  # states past the point where the bare learner crashed
    # With dagger.shield_second_gear the filter backs the stopped car off in reverse instead.
    obs2, _, _, swapped = run(True, True)
    assert swapped["collided"] == 0 and swapped["gear_swaps"] > 0
    assert obs2["observation"][:, 4].min() < 0 <= obs["observation"][:, 4].min()  # it went backwards


@pytest.mark.rl
def test_with_beta_one_a_dagger_round_is_the_experts_own_episode(require_module):
    require_module("stable_baselines3")
    import gymnasium as gym

    from evaluation.registry import make_policy
    from planners.base import run_episode
    from planners.rl.dagger import ShadowExpert, rollouts

    sc = Scenario.from_case_id(CASES[0])
    obs, labels, _, counts = rollouts(
        None, ShadowExpert(make_policy("guide-only"), 6), [sc], beta=1.0, max_steps=1800, seed=0
    )
    record: list = []
    info, steps = run_episode(gym.make("MirrorPark-v0"), make_policy("guide-only"), sc, record=record)
    assert info["is_success"] and counts["parked"] == 1 and len(labels) == steps
    assert np.array_equal(labels, np.array([r[0] for r in record[1:]], np.float32))


@pytest.mark.rl
def test_dagger_training_cases_leave_the_evaluation_samples_out():
    from mirrorpark_env.grid import Grid
    from planners.rl.dagger import training_cases

    grid = Grid.from_config()
    cases = training_cases(grid, 300, seed=1, types=("parallel", "reverse", "angle"))
    held_out = {grid.scenario(int(i)).case_id for s in ("smoke", "standard") for i in grid.sample_indices(s)}
    assert len(cases) == 300 and [c.parking_type.value for c in cases].count("angle") == 100
    assert not held_out & {c.case_id for c in cases}
    assert training_cases(grid, 300, seed=1, types=("parallel", "reverse", "angle")) == cases


@pytest.mark.rl
def test_slot_frame_features_are_the_pose_seen_from_the_target(require_module):
    require_module("stable_baselines3")
    import math

    import torch
    from gymnasium import spaces

    from planners.rl.features import SlotFrameFeatures

    box = spaces.Box(-np.inf, np.inf, (13,), np.float32)
    f = SlotFrameFeatures(spaces.Dict({"observation": box, "desired_goal": spaces.Box(-np.inf, np.inf, (4,))}))
    th = math.radians(60)  # the target at (2, 3) m, heading 60 deg; the car 1 m behind it, 10 deg to the left
    o = torch.zeros(1, 13)
    x0, y0 = (2 - math.cos(th)) / 10, (3 - math.sin(th)) / 10
    o[0, :4] = torch.tensor([x0, y0, math.cos(th + 0.1745), math.sin(th + 0.1745)])
    o[0, 4:] = torch.arange(9) + 1.0
    g = torch.tensor([[0.2, 0.3, math.cos(th), math.sin(th)]])
    x = f({"observation": o, "desired_goal": g})[0]
    assert x[:2].tolist() == pytest.approx([-1 / 5, 0.0], abs=1e-6)
    assert x[2:4].tolist() == pytest.approx([math.tanh(-1 / 0.3), 0.0], abs=1e-6)
    assert x[4:6].tolist() == pytest.approx([math.cos(0.1745), math.sin(0.1745)], abs=1e-6)
    assert x[6:].tolist() == pytest.approx(list(range(1, 10)))


@pytest.mark.rl
def test_a_model_trained_with_a_lidar_measures_it_where_the_env_gives_none(tmp_path, require_module):
    """The ranges the policy measures for itself are the env's own, bit for bit, along a drive."""
    require_module("stable_baselines3")
    import gymnasium as gym

    from planners.rl.config import load_rl_config
    from planners.rl.dagger import dagger
    from planners.rl.policy import RLPolicy

    lidar = {"rays": 8, "max_range": 5.0}
    cfg = load_rl_config(
        "configs/rl_dagger.yaml",
        {"lidar": lidar, "dagger": {"cases_per_round": 3, "workers": 1}, "bc": {"epochs": 1}},
    )
    dagger(cfg, None, tmp_path, rounds=1, progress=False, make_expert=make_policy)
    policy = RLPolicy(tmp_path / "model.zip")
    plain, ringed = gym.make("MirrorPark-v0"), gym.make("MirrorPark-v0", config={"lidar": lidar})
    sc = Scenario.from_case_id(CASES[0])
    obs, info = plain.reset(options={"scenario": sc})
    want, _ = ringed.reset(options={"scenario": sc})
    policy.reset(info["geometry"])
    for _ in range(15):
        got = policy.observation(obs, info)
        assert "lidar" not in obs and np.array_equal(got["lidar"], want["lidar"])
        action = policy.act(obs, info)
        obs, _, _, _, info = plain.step(action)
        want, *_ = ringed.step(action)
    assert np.array_equal(obs["observation"], want["observation"])


@pytest.mark.rl
def test_cloning_demonstrations_without_the_lidar_the_config_asks_for_is_refused(require_module):
    require_module("stable_baselines3")
    from mirrorpark_env.grid import Grid
    from planners.rl.bc import fit_actor
    from planners.rl.config import load_rl_config
    from planners.rl.train import make_model, make_train_env

    cfg = load_rl_config("configs/rl_dagger.yaml", {"lidar": {"rays": 8, "max_range": 5.0}})
    model = make_model(cfg, make_train_env(cfg, Grid.from_config()))
    obs = {k: np.zeros((4, *space.shape), np.float32) for k, space in model.observation_space.spaces.items()}
    del obs["lidar"]
    with pytest.raises(ValueError, match=r"no lidar observations.*lidar.rays: 8"):
        fit_actor(model, obs, np.zeros((4, 2), np.float32), cfg, progress=False)


def test_an_expert_that_replans_moving_tells_a_drifted_learner_how_to_go_on():
    """After a drift the tracking expert brakes to a stand before it plans again; with
    ``replan_moving`` (DAgger's option) it plans at once from the moving car."""
    import gymnasium as gym

    from evaluation.registry import make_policy

    sc = Scenario.from_case_id(CASES[1])
    env = gym.make("MirrorPark-v0")

    def speeds_at_plans(replan_moving: bool) -> list[float]:
        """A learner that does what the expert says, but holds its wheels straight after
        2.5 s: it drifts off the expert's path while driving."""
        expert = make_policy("guide-only")
        expert.inner.replan_moving = replan_moving
        o, info = env.reset(options={"scenario": sc})
        expert.reset(info["geometry"])
        out = []
        for t in range(60):
            n = len(expert.inner.stats)
            a = expert.act(o, info)
            if len(expert.inner.stats) > n:
                out.append(abs(info["vehicle_state"].v))
            o, _, term, trunc, info = env.step(np.array([a[0], a[1] if t < 25 else 0.0], np.float32))
            if term or trunc:
                break
        return out

    standing, moving = speeds_at_plans(False), speeds_at_plans(True)
    assert len(standing) == 2 and max(standing) <= 0.02  # the replan waits for the car to stand
    assert len(moving) == 2 and moving[1] > 0.5  # the replan comes while the car drives on


@pytest.mark.rl
def test_a_markov_expert_answers_from_the_state_alone():
    """With ``markov`` the expert's label at a state does not depend on how the car got
    there: an expert that rode along from the start and one asked for the first time give
    the same action. The riding-along expert does not (fresh, it would first stop)."""
    import gymnasium as gym

    from evaluation.registry import make_policy

    sc = Scenario.from_case_id(CASES[1])
    env = gym.make("MirrorPark-v0")
    o, info = env.reset(options={"scenario": sc})
    geometry = info["geometry"]
    along, along_markov = make_policy("guide-only"), make_policy("guide-only")
    along_markov.inner.markov = True
    along.reset(geometry)
    along_markov.reset(geometry)
    for t in range(30):  # the learner: the expert's own action, wheels held straight from 2.5 s on
        a = along.act(o, info)
        along_markov.act(o, info)
        o, _, term, trunc, info = env.step(np.array([a[0], a[1] if t < 25 else 0.0], np.float32))
        assert not (term or trunc)
    assert abs(info["vehicle_state"].v) > 0.3  # a moving state, off the first plan's path
    fresh, fresh_markov = make_policy("guide-only"), make_policy("guide-only")
    fresh_markov.inner.markov = True
    for p in (fresh, fresh_markov):
        p.reset(geometry)
    np.testing.assert_array_equal(along_markov.act(o, info), fresh_markov.act(o, info))
    assert not np.array_equal(along.act(o, info), fresh.act(o, info))


@pytest.mark.rl
def test_a_markov_expert_must_price_the_gear_it_starts_in(require_module):
    require_module("stable_baselines3")
    from planners.rl.dagger import ShadowExpert

    with pytest.raises(ValueError, match="expert_markov.*hybrid-astar"):
        ShadowExpert(make_policy("hybrid-astar"), 6, markov=True)
    assert ShadowExpert(make_policy("guide-only"), 6, markov=True).policy.inner.markov


@pytest.mark.rl
@pytest.mark.parametrize("gear", [False, True])
def test_an_interrupted_dagger_run_resumes_to_the_weights_of_one_without_a_break(gear, tmp_path, require_module):
    """Two rounds in one go, and one round then ``--resume --dagger-rounds 2``: the same
    model (and gear head), bit for bit, and the same round log; a folder with no finished
    round is refused."""
    require_module("stable_baselines3")
    import torch

    from evaluation.cli import main as cli
    from planners.rl.config import load_rl_config
    from planners.rl.dagger import dagger
    from planners.rl.gear import GearedModel
    from planners.rl.policy import RLPolicy

    dc = {"cases_per_round": 2, "workers": 1, "max_steps": 40, "gear": gear, "expert_markov": gear}
    over = {"lidar": {"rays": 8}, "dagger": dc, "bc": {"epochs": 2}}
    cfg = load_rl_config("configs/rl_dagger.yaml", over)
    whole = dagger(cfg, None, tmp_path / "whole", rounds=2, progress=False, make_expert=make_policy)
    assert (tmp_path / "whole" / "learning_curve.png").stat().st_size > 0
    first = dagger(cfg, None, tmp_path / "cut", rounds=1, progress=False, make_expert=make_policy)
    assert [r["round"] for r in first["rounds"]] == [1]
    assert cli(["train-rl", "--resume", str(tmp_path / "cut"), "--dagger-rounds", "2"]) == 0
    resumed = json.loads((tmp_path / "cut" / "train.json").read_text())
    drop = lambda log: [{k: v for k, v in r.items() if k != "wall_s"} for r in log]  # noqa: E731
    assert drop(resumed["rounds"]) == drop(whole["rounds"]) and resumed["samples"] == whole["samples"]
    pa, pb = RLPolicy(tmp_path / "whole" / "model.zip").model, RLPolicy(tmp_path / "cut" / "model.zip").model
    assert isinstance(pa, GearedModel) == isinstance(pb, GearedModel) == gear
    nets = [(pa.actor, pb.actor)] + ([(pa.head, pb.head)] if gear else [])
    for na, nb in nets:
        a, b = na.state_dict(), nb.state_dict()
        assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert ("gear_head" in resumed) == gear and (not gear or resumed["gear_head"] == whole["gear_head"])
    assert sorted(p.name for p in (tmp_path / "cut" / "rounds").glob("data-*")) == ["data-r2.npz"]
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "config.json").write_text(cfg.model_dump_json())
    (tmp_path / "empty" / "dagger.json").write_text('{"demos": null, "rounds": 2}')
    assert cli(["train-rl", "--resume", str(tmp_path / "empty")]) == 2


@pytest.mark.rl
def test_a_slower_expert_keeps_to_its_cruising_speed_and_still_parks(require_module):
    require_module("stable_baselines3")
    import gymnasium as gym

    from planners.base import run_episode
    from planners.rl.dagger import ShadowExpert

    sc = Scenario.from_case_id(CASES[0])
    top = {}
    for cruise in (None, 0.5):
        expert = ShadowExpert(make_policy("guide-only"), 20, markov=True, cruise_speed=cruise)
        trace: list = []
        info, _ = run_episode(gym.make("MirrorPark-v0"), expert.policy, sc, trace=trace)
        assert info["is_success"]
        top[cruise] = max(abs(t["vehicle_state"].v) for t in trace)
    assert top[0.5] < 0.6 and top[None] > 0.9  # the tracker overshoots its reference by a few per cent


@pytest.mark.rl
@pytest.mark.parametrize(("loss", "want"), [("mse", 0.45), ("l1", 0.9)])
def test_an_l1_fit_takes_the_majoritys_gear_where_mse_stands_between(loss, want, require_module):
    """Six labels of +0.9 and two of -0.9 at one state: the mean is 0.45 (a creep), the
    median +0.9 (the majority's gear)."""
    require_module("stable_baselines3")
    from mirrorpark_env.grid import Grid
    from planners.rl.bc import fit_actor
    from planners.rl.config import load_rl_config
    from planners.rl.train import make_model, make_train_env

    cfg = load_rl_config("configs/rl_dagger.yaml", {"bc": {"epochs": 300, "batch_size": 8, "loss": loss}})
    model = make_model(cfg, make_train_env(cfg, Grid.from_config()))
    model.observation_space.seed(0)
    state = {k: v[None] for k, v in model.observation_space.sample().items()}
    obs = {k: np.repeat(v, 8, axis=0) for k, v in state.items()}
    actions = np.array([[0.9, 0.2]] * 6 + [[-0.9, 0.2]] * 2, np.float32)
    fit_actor(model, obs, actions, cfg, progress=False)
    accel, steer = model.predict(state, deterministic=True)[0][0]
    assert accel == pytest.approx(want, abs=0.05)
    assert steer == pytest.approx(0.2, abs=0.05)


@pytest.mark.rl
def test_a_markov_experts_labels_at_a_stand_carry_the_gear_it_goes_in(require_module):
    """Where the car stands the Markov expert names the gear its path starts in: where it
    goes at once, the gear of its acceleration; where it holds, re-steering first, the gear
    it will go in. Moving, it names none."""
    require_module("stable_baselines3")
    from planners.rl.dagger import ShadowExpert, rollouts
    from planners.rl.gear import standing

    sc = Scenario.from_case_id(CASES[0])
    obs, labels, gears, counts = rollouts(
        None, ShadowExpert(make_policy("guide-only"), 20, markov=True), [sc], beta=1.0, max_steps=1800, seed=0
    )
    assert counts["parked"] == 1
    stand = standing(obs)
    assert not gears[~stand].any() and set(np.unique(gears[stand])) <= {-1, 0, 1}
    going = stand & (np.abs(labels[:, 0]) > 0.05) & (gears != 0)
    assert going.sum() >= 2 and (np.sign(labels[going, 0]) == gears[going]).all()
    holding = stand & (np.abs(labels[:, 0]) <= 0.05) & (gears != 0)
    assert holding.sum() > 0  # re-steering while it stands, its gear already named
    assert {-1, 1} <= set(gears.tolist())  # this case parks with a switch


@pytest.mark.rl
def test_a_gear_head_chooses_the_gear_and_a_standing_learner_resteers_then_goes(tmp_path, require_module):
    """Two standing states labelled forward and back: the fitted head tells them apart. A
    geared model standing with its wheels away from its own steering command holds; with
    them there it goes in the head's gear; moving, it acts as the model does. Saved and
    loaded, it answers the same."""
    require_module("stable_baselines3")
    from mirrorpark_env.grid import Grid
    from planners.rl.config import load_rl_config
    from planners.rl.gear import GearedModel, fit_head, load_head, make_head
    from planners.rl.train import make_model, make_train_env

    cfg = load_rl_config("configs/rl_dagger.yaml", {"bc": {"epochs": 200, "batch_size": 8}})
    model = make_model(cfg, make_train_env(cfg, Grid.from_config()))
    model.observation_space.seed(1)
    states = [{k: v[None].copy() for k, v in model.observation_space.sample().items()} for _ in range(2)]
    for s in states:
        s["observation"][0, 4] = 0.0  # standing
    obs = {k: np.concatenate([s[k] for s in states] * 4) for k in states[0]}
    gears = np.array([1, -1] * 4, np.int8)
    head = make_head(model.actor.features_dim)
    fit_head(model, head, obs, gears, cfg, progress=False)
    geared = GearedModel(model, head, (0.4, -0.5))
    assert geared.gear_logits(states[0])[0] > 0 > geared.gear_logits(states[1])[0]
    for s, go in zip(states, (0.4, -0.5)):
        steer = model.predict(s, deterministic=True)[0][0, 1]
        s["observation"][0, 6] = steer  # the wheels where the actor wants them
        assert geared.predict(s)[0][0] == pytest.approx([go, steer], abs=1e-3)  # its steering sees the wheels
        s["observation"][0, 6] = steer - 0.5 if steer > 0 else steer + 0.5
        assert geared.predict(s)[0][0, 0] == 0.0  # re-steering first
        moving = {k: v.copy() for k, v in s.items()}
        moving["observation"][0, 4] = 0.3
        np.testing.assert_array_equal(geared.predict(moving)[0], model.predict(moving, deterministic=True)[0])
    assert geared.other_gear(np.array([0.4, 0.2]))[0] == -0.5 and geared.other_gear(np.array([-0.5, 0.2]))[0] == 0.4
    geared.save(tmp_path / "model.zip")
    loaded = load_head(model, tmp_path / "model.zip")
    assert loaded.go == (0.4, -0.5)
    batch = {k: np.concatenate([s[k] for s in states]) for k in states[0]}
    np.testing.assert_array_equal(loaded.predict(batch)[0], geared.predict(batch)[0])
    assert load_head(model, tmp_path / "none.zip") is None


def test_a_gear_head_needs_the_markov_expert():
    from planners.rl.config import load_rl_config

    with pytest.raises(ValueError, match="dagger.gear"):
        load_rl_config("configs/rl_dagger.yaml", {"dagger": {"gear": True, "expert_markov": False}})


def test_the_filters_second_gear_in_dagger_needs_the_filter():
    from planners.rl.config import load_rl_config

    with pytest.raises(ValueError, match="dagger.shield_second_gear"):
        load_rl_config("configs/rl_dagger.yaml", {"dagger": {"shield_second_gear": True, "shield": False}})
