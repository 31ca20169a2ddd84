"""Truth model: closed-form checks, Theorem 2, action mapping."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mirrorpark_env.vehicle import TruthModel, VehicleParams, footprint, from_action, to_action

P = VehicleParams.table_ii()


def run(model: TruthModel, state, commands):
    s = np.asarray(state, float)
    out = [s]
    for a, d in commands:
        s = model.step(s, a, d)[-1, :6]
        out.append(s)
    return np.array(out)


def test_table_ii_values():
    assert P.length == pytest.approx(3.82)
    assert P.r_min == pytest.approx(2.5 / math.tan(0.6))
    assert VehicleParams.table_ii() == P


def test_constant_speed_and_steer_follow_the_circular_arc():
    """With lags settled, speed and steering constant: an exact circle of radius l/tan(delta)."""
    m = TruthModel(P, 0.1, 0.01)
    v, delta, th0 = 1.5, 0.4, 0.3
    R = P.wheelbase / math.tan(delta)
    traj = run(m, [1.0, 2.0, th0, v, 0.0, delta], [(0.0, delta)] * 40)
    t = 0.1 * np.arange(41)
    th = th0 + v * t / R
    np.testing.assert_allclose(traj[:, 2], th, atol=1e-12)
    np.testing.assert_allclose(traj[:, 0], 1.0 + R * (np.sin(th) - math.sin(th0)), atol=1e-9)
    np.testing.assert_allclose(traj[:, 1], 2.0 - R * (np.cos(th) - math.cos(th0)), atol=1e-9)
    np.testing.assert_allclose(traj[:, 3], v)


def test_lags_are_first_order_and_exact():
    m = TruthModel(P, 0.1, 0.01)
    traj = run(m, [0, 0, 0, 0, 0, 0], [(2.0, 0.5)] * 5)
    t = 0.1 * np.arange(6)
    np.testing.assert_allclose(traj[:, 4], 2.0 * (1 - np.exp(-t / P.tau_accel_s)), atol=1e-12)
    np.testing.assert_allclose(traj[:, 5], 0.5 * (1 - np.exp(-t / P.tau_steer_s)), atol=1e-12)
    # v = integral of a, in closed form.
    v = 2.0 * (t - P.tau_accel_s * (1 - np.exp(-t / P.tau_accel_s)))
    np.testing.assert_allclose(traj[:, 3], v, atol=1e-12)


def test_straight_line_distance_matches_closed_form():
    m = TruthModel(P, 0.1, 0.01)
    traj = run(m, [0, 0, 0, 0, 0, 0], [(1.0, 0.0)] * 10)
    t, tau = 1.0, P.tau_accel_s
    x = t**2 / 2 - tau * (t - tau * (1 - math.exp(-t / tau)))
    assert traj[-1, 0] == pytest.approx(x, abs=1e-5)
    assert traj[-1, 1] == 0.0


def test_commands_and_speed_saturate():
    m = TruthModel(P, 0.1, 0.01)
    traj = run(m, [0, 0, 0, 0, 0, 0], [(50.0, 2.0)] * 40)
    assert traj[:, 3].max() == pytest.approx(P.speed_max)
    assert traj[:, 4].max() <= P.accel_max + 1e-12
    assert np.abs(traj[:, 5]).max() <= P.max_steer_rad + 1e-12


@pytest.mark.parametrize("substep", [0.01, 0.05])
@pytest.mark.parametrize("saturating", [False, True])
def test_rollout_equals_chained_steps(substep, saturating):
    """``rollout`` (open-loop plans) is ``step`` chained: every sub-step's row, bit for bit,
    including gear changes, straight stretches and speed saturation."""
    m = TruthModel(P, 0.1, substep)
    rng = np.random.default_rng(3)
    cmds = np.stack([rng.uniform(-3, 3, 60), rng.uniform(-0.7, 0.7, 60)], axis=1)  # beyond bounds: clipped
    cmds[20:30, 1] = 0.0  # straight: the chord's small-angle branch
    if saturating:
        cmds[:, 0] = 5.0
    state = np.array([1.0, -2.0, 0.3, 0.4 if not saturating else 2.5, 0.2, -0.1])
    chained, s = [], state
    for a, d in cmds:
        sub = m.step(s, a, d)
        chained.append(sub)
        s = sub[-1, :6]
    chained = np.concatenate(chained)
    fast = m.rollout(state, cmds)
    assert fast.shape == chained.shape == (60 * round(0.1 / substep), 7)
    assert np.array_equal(fast, chained)
    assert (chained[:, 3].max() >= P.speed_max - 1e-12) == saturating


def _reference_step(m: TruthModel, state, a_cmd: float, delta_cmd: float) -> np.ndarray:
    """The truth model's step written out in Python (the module docstring's model): exact
    lags, arcs of the sub-step's mean speed at its mid-step steering, commands clipped."""
    p = m.params
    a_cmd, delta_cmd = min(max(a_cmd, p.accel_min), p.accel_max), min(max(delta_cmd, -p.max_steer_rad), p.max_steer_rad)
    x, y, th, v, a0, d0 = map(float, state[:6])
    h, inv_l = m.h, 1.0 / p.wheelbase
    dv_lag = p.tau_accel_s * (1.0 - math.exp(-h / p.tau_accel_s))
    da, dd = a0 - a_cmd, d0 - delta_cmd
    rows = []
    for k in range(m.n):
        v1 = v + a_cmd * h + da * math.exp(-k * h / p.tau_accel_s) * dv_lag
        v1 = p.speed_min if v1 < p.speed_min else (p.speed_max if v1 > p.speed_max else v1)
        ds = 0.5 * (v + v1) * h
        dth = ds * math.tan(delta_cmd + dd * math.exp(-(k + 0.5) * h / p.tau_steer_s)) * inv_l
        half = 0.5 * dth
        chord = ds * math.sin(half) / half if abs(half) > 1e-12 else ds
        x += chord * math.cos(th + half)
        y += chord * math.sin(th + half)
        th += dth
        v = v1
        a = a_cmd + da * math.exp(-(k + 1) * h / p.tau_accel_s)
        d = delta_cmd + dd * math.exp(-(k + 1) * h / p.tau_steer_s)
        rows.append((x, y, th, v, a, d, abs(chord)))
    return np.array(rows)


@pytest.mark.parametrize("substep", [0.01, 0.05])
def test_the_compiled_step_is_the_python_reference_bit_for_bit(substep):
    """``step`` (the compiled ``truth_kernel.truth_step``) against the model written out in
    Python, on random states and commands: standing cars, straight wheels, saturated speeds
    and commands beyond their bounds."""
    m = TruthModel(P, 0.1, substep)
    rng = np.random.default_rng(0)
    k = 300
    states = np.column_stack(
        [
            rng.uniform(-5, 5, k),
            rng.uniform(-5, 5, k),
            rng.uniform(-3, 3, k),
            rng.uniform(-2.5, 2.5, k),
            rng.uniform(-3, 3, k),
            rng.uniform(-0.6, 0.6, k),
        ]
    )
    a_cmd, d_cmd = rng.uniform(-6, 4, k), rng.uniform(-0.8, 0.8, k)
    states[:5, 3], states[:5, 4], a_cmd[:5] = 0.0, 0.0, 0.0  # standing still
    states[5:10, 5], d_cmd[5:10] = 0.0, 0.0  # straight
    states[10:15, 3], a_cmd[10:15] = P.speed_max, 4.0  # saturating
    for i in range(k):
        assert np.array_equal(m.step(states[i], a_cmd[i], d_cmd[i]), _reference_step(m, states[i], a_cmd[i], d_cmd[i]))


@pytest.mark.parametrize("lags", [False, True])
def test_theorem_2_negated_commands_give_the_point_reflected_path(lags):
    """Eq. (7)-(9): same start, opposite speed, negated commands -> x, y negated, theta equal."""
    params = P if lags else dataclasses.replace(P, tau_accel_s=1e-9, tau_steer_s=1e-9)
    m = TruthModel(params, 0.1, 0.01)
    rng = np.random.default_rng(0)
    # Within the symmetric part of the bounds (|a| <= 3): a negated command is not clipped.
    accel = 1.5 * np.sin(np.arange(60) / 4.0)
    cmds = list(zip(accel, rng.uniform(-0.6, 0.6, 60)))
    a0, d0 = (0.7, -0.2) if lags else (0.0, 0.0)
    fwd = run(m, [0, 0, 0.4, 1.2, a0, d0], cmds)
    back = run(m, [0, 0, 0.4, -1.2, -a0, -d0], [(-a, -d) for a, d in cmds])
    assert np.abs(fwd[:, 3]).max() < P.speed_max  # no saturation, so the symmetry is exact
    np.testing.assert_allclose(back[:, 0], -fwd[:, 0], atol=1e-12)
    np.testing.assert_allclose(back[:, 1], -fwd[:, 1], atol=1e-12)
    np.testing.assert_allclose(back[:, 2], fwd[:, 2], atol=1e-12)
    np.testing.assert_allclose(back[:, 3], -fwd[:, 3], atol=1e-12)


def test_footprint_corners():
    c = footprint(P, 1.0, 2.0, math.pi / 2)
    np.testing.assert_allclose(c[0], [1.0 - 0.835, 2.0 + 3.11])  # front-left
    np.testing.assert_allclose(c[2], [1.0 + 0.835, 2.0 - 0.71])  # rear-right


def test_action_mapping_round_trip_and_zero():
    for a, d in [(0.0, 0.0), (3.0, 0.6), (-5.0, -0.6), (-2.0, 0.3), (1.5, -0.1)]:
        u = to_action(P, a, d)
        assert from_action(P, u) == pytest.approx((a, d), abs=1e-6)
    assert from_action(P, [0.0, 0.0]) == (0.0, 0.0)
    assert from_action(P, [7.0, -3.0]) == pytest.approx((3.0, -0.6))


@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf]])
def test_nan_action_is_an_error(bad):
    with pytest.raises(ValueError, match="action: must be finite"):
        from_action(P, bad)


def test_wrong_action_shape_is_an_error():
    with pytest.raises(ValueError, match=r"action: expected shape \(2,\)"):
        from_action(P, [0.1, 0.2, 0.3])


def test_substep_must_divide_dt():
    with pytest.raises(ValueError, match="substep"):
        TruthModel(P, 0.1, 0.03)
