"""Street trajectories, the lagged adversary, and the CSV loader's errors."""

import numpy as np
import pytest

from veriloc_rt.config import SceneConfig, TrajectoryConfig
from veriloc_rt.errors import InputError
from veriloc_rt.world.scene.canyon import urban_canyon
from veriloc_rt.world.trajectory import (check_points, follower, generate_street_trajectory,
                                         load_csv_trajectory)


@pytest.fixture(scope="module")
def canyon():
    return urban_canyon(SceneConfig(extent_m=300.0))


@pytest.fixture(scope="module")
def traj(canyon):
    cfg = TrajectoryConfig(num_points=600, region_m=150.0)
    return generate_street_trajectory(cfg, canyon, np.random.default_rng(4))


def test_every_point_is_on_a_street_centre_line(traj, canyon):
    xy = traj.pos[:, :2]
    off = np.abs(xy - canyon.pitch * np.round(xy / canyon.pitch))
    # on a centre line: one coordinate is a multiple of the pitch (float tolerance 1e-6 m)
    assert np.all(off.min(axis=1) < 1e-6)
    assert not canyon.inside_building(xy).any()
    assert np.all(np.abs(xy) <= 150.0 + 1e-9)
    assert np.allclose(traj.pos[:, 2], 1.5)


def test_time_base_and_kinematics(traj):
    cfg = TrajectoryConfig()
    assert traj.num_points == 600
    assert np.allclose(np.diff(traj.t), 1.0)
    speed = np.diff(traj.s) / np.diff(traj.t)
    assert speed.min() >= -1e-9  # never drives backwards along its path
    assert speed.max() <= cfg.max_speed_mps + 1e-6
    # braking and accelerating are limited: mean speed over 1 s changes by <= 2 a dt
    # (a sample window straddles at most two accelerating phases)
    assert np.abs(np.diff(speed)).max() <= 2 * cfg.accel_mps2 + 1e-6
    stopped = speed < 1e-3
    assert 0.02 < stopped.mean() < 0.6, "non-uniform speed: some stops, mostly moving"
    heading = np.arctan2(np.diff(traj.pos[:, 1]), np.diff(traj.pos[:, 0]))[~stopped]
    assert len(np.unique(np.round(heading, 3))) >= 2, "the route turns"


def test_adversary_follows_the_same_path_lagged(traj):
    adv = follower(traj, 10, 5.0)
    k = np.arange(10, traj.num_points)
    lagged = traj.s[k - 10]
    expect = np.minimum(lagged, traj.s[k] - 5.0)
    assert np.allclose(adv.s[k], expect)
    assert np.all(traj.s - adv.s >= 5.0 - 1e-9)
    # where the UE moved enough, the adversary is exactly where the UE was 10 points before
    moved = traj.s[k] - lagged >= 5.0
    assert np.allclose(adv.pos[k[moved]], traj.pos[k[moved] - 10], atol=1e-9)


def _write(tmp_path, text):
    f = tmp_path / "t.csv"
    f.write_text(text)
    return f


def test_csv_round_trip(tmp_path):
    f = _write(tmp_path, "t,x,y\n0,0,0\n1,0,10\n2,5,35\n")
    tr = load_csv_trajectory(f, TrajectoryConfig())
    assert tr.num_points == 3 and np.allclose(tr.pos[:, 2], 1.5)
    assert np.allclose(tr.s, [0, 10, 10 + np.hypot(5, 25)])
    assert np.allclose(tr.vel[0], [0, 10, 0])


@pytest.mark.parametrize("text, where, words", [
    ("x,y\n1,2\n", "t.csv", "header"),
    ("t,x,y\n0,0,0\n1,a,0\n", "t.csv:3", "non-numeric"),
    ("t,x,y\n0,0,0\n0,0,5\n", "t.csv:3", "increase"),
    ("t,x,y\n0,0,0\n1,0,nan\n", "t.csv:3", "non-finite"),
    ("t,x,y\n0,0,0\n", "t.csv", "at least 2"),
    ("t,x,y\n0,0,0\n1,0\n", "t.csv:3", "columns"),
])
def test_csv_errors_name_file_and_row(tmp_path, text, where, words):
    f = _write(tmp_path, text)
    with pytest.raises(InputError) as exc:
        load_csv_trajectory(f, TrajectoryConfig())
    assert exc.value.field.endswith(where) and words in exc.value.problem


def test_points_in_buildings_or_outside_are_rejected(canyon):
    inside = np.array([[0.0, 0.0, 1.5], [canyon.pitch / 2, canyon.pitch / 2, 1.5]])
    with pytest.raises(InputError, match="point 1 .* inside a building"):
        check_points(canyon, inside, "trajectory", "t.csv")
    outside = np.array([[0.0, 0.0, 1.5], [10_000.0, 0.0, 1.5]])
    with pytest.raises(InputError, match="point 1 .* outside the scene"):
        check_points(canyon, outside, "trajectory", "t.csv")
    above_roof = np.array([[canyon.pitch / 2, canyon.pitch / 2, 20.0]])
    check_points(canyon, above_roof, "trajectory", "t.csv")  # over a 15 m roof is fine


def test_region_too_small_is_an_input_error(canyon):
    with pytest.raises(InputError, match="trajectory.region_m"):
        generate_street_trajectory(TrajectoryConfig(region_m=10.0), canyon, np.random.default_rng(0))
