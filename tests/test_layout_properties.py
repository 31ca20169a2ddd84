"""Layouts as users write them, generated (hypothesis): loading one either succeeds, and the
environment then resets in it and steps, or fails with the project's own one-line error
(``ValueError``) naming what is wrong; never another exception."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

import mirrorpark_env  # noqa: F401
from mirrorpark_env.layout_io import load_layouts

number = st.floats(-30, 30, allow_nan=False)
coord = st.one_of(
    number,
    number,
    number,
    st.sampled_from([0.0, 1e300, -1e300, 1e9, float("nan"), float("inf")]),
    st.booleans(),
    st.text(max_size=3),
)
point = st.lists(coord, min_size=2, max_size=2)
odd_pose = st.fixed_dictionaries({"x": coord, "y": coord, "heading": st.one_of(st.floats(-7, 7), coord)})
pose = st.one_of(st.fixed_dictionaries({"x": number, "y": number, "heading": st.floats(-7, 7)}), odd_pose)
polygon = st.lists(point, min_size=2, max_size=6)
slot = st.one_of(
    st.none(),
    st.just("infer"),
    st.fixed_dictionaries(
        {"corners": st.lists(point, min_size=3, max_size=5), "type": st.sampled_from(["parallel", "reverse", "bad"])}
    ),
)


@st.composite
def box(draw) -> list[list[float]]:
    """A rectangle somewhere in the scene: the obstacles users mostly write."""
    x, y = draw(number), draw(number)
    w, h = draw(st.floats(0.2, 8)), draw(st.floats(0.2, 8))
    return [[x, y], [x + w, y], [x + w, y + h], [x, y + h]]


layout = st.fixed_dictionaries(
    {"start": pose, "target": pose, "obstacles": st.lists(st.one_of(box(), box(), polygon), max_size=4)},
    optional={"slot": slot, "boundary": st.one_of(box(), polygon), "name": st.text(min_size=1, max_size=8)},
)


@pytest.mark.property
@given(data=layout)
def test_a_written_layout_loads_and_runs_or_is_refused_in_one_line(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("layout") / "scene.json"
    path.write_text(json.dumps(data))
    try:
        layouts = load_layouts(path)
    except ValueError as err:
        assert str(err).startswith(str(path)) and "\n" not in str(err)
        event("refused")
        return
    event("loaded")
    env = gym.make("MirrorPark-v0")
    for lay in layouts:
        env.reset(options={"layout": lay})
        for _ in range(3):
            _, _, terminated, truncated, _ = env.step(np.zeros(2, np.float32))
            if terminated or truncated:
                break
