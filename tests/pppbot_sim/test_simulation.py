"""The MuJoCo simulation: the robot's build, driving accuracy, lidar geometry, IMU, reset, divergence."""
from __future__ import annotations

import math
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import process_xacro
from pppbot_sim.errors import SimulationDiverged, SpawnError
from pppbot_sim.mj_build import ROBOT_GROUP, SpawnPose
from pppbot_sim.runner import PhysicsRunner
from pppbot_sim.sensors import LidarSpec, finalize_ranges
from pppbot_sim.simulation import Event, EventKind, Schedule, Simulation, load_world
from pppbot_sim.wheel_slip import SlipModel, WheelSlip
from pppbot_sim.worlds import find_world, model_paths

DATA = Path(__file__).parent / "data"
ROBOT = parse_urdf(process_xacro())
WHEEL_RADIUS, WHEEL_SEPARATION = 0.05, 0.35


def make_sim(world: str | Path = "empty", spawn: SpawnPose = SpawnPose(), seed: int = 0, robot=ROBOT) -> Simulation:
    path = find_world(str(world))
    spec, _ = load_world(path, model_paths(path))
    return Simulation(spec, robot, spawn, seed=seed)


def run_for(sim: Simulation, seconds: float) -> None:
    end = sim.time_s + seconds
    while sim.time_s < end - 0.5 * sim.step_s:
        sim.advance(max(1, int(round((end - sim.time_s) / sim.step_s))))


def drive(sim: Simulation, v: float, w: float) -> None:
    """Wheel speeds of a differential drive for body velocities v (m/s), w (rad/s)."""
    left = (v - w * WHEEL_SEPARATION / 2) / WHEEL_RADIUS
    right = (v + w * WHEEL_SEPARATION / 2) / WHEEL_RADIUS
    sim.set_wheel_velocities({"left_wheel_joint": left, "right_wheel_joint": right})


def test_robot_build_fuses_fixed_links_and_keeps_frames():
    sim = make_sim()
    m = sim.model
    robot_bodies = [m.body(i).name for i in range(m.nbody) if m.body(i).name.startswith("ppp_bot/")]
    assert sorted(robot_bodies) == ["ppp_bot/base_link", "ppp_bot/left_wheel", "ppp_bot/right_wheel"]
    total = sum(link.inertial.mass for link in ROBOT.links.values() if link.inertial)
    robot_mass = sum(m.body(b).mass[0] for b in robot_bodies)
    assert robot_mass == pytest.approx(total)
    sites = {m.site(i).name for i in range(m.nsite)}
    assert {f"ppp_bot/{link}" for link in ROBOT.links} <= sites
    data = sim.data
    mujoco.mj_forward(m, data)
    lidar = data.site_xpos[m.site("ppp_bot/lidar_frame").id]
    np.testing.assert_allclose(lidar, [0.05, 0.0, 0.05 + 0.15], atol=1e-9)
    for joint in ("left_wheel_joint", "right_wheel_joint"):
        actuator = m.actuator(f"ppp_bot/{joint}::velocity")
        np.testing.assert_allclose(actuator.ctrlrange, [-10, 10])
    assert all(m.geom_group[g] == ROBOT_GROUP for g in range(m.ngeom) if m.geom(g).name.startswith("ppp_bot/"))


def test_half_a_metre_per_second_for_four_seconds_is_two_metres():
    sim = make_sim()
    run_for(sim, 0.5)  # settle on the ground
    start = sim.ground_truth().position.copy()
    drive(sim, 0.5, 0.0)
    run_for(sim, 4.0)
    travelled = np.linalg.norm(sim.ground_truth().position[:2] - start[:2])
    assert travelled == pytest.approx(2.0, rel=0.03)
    assert abs(sim.ground_truth().yaw) < 0.01


def test_one_radian_per_second_for_four_seconds_is_four_radians():
    sim = make_sim()
    run_for(sim, 0.5)
    drive(sim, 0.0, 1.0)
    turned, last = 0.0, sim.ground_truth().yaw
    for _ in range(400):
        run_for(sim, 0.01)
        yaw = sim.ground_truth().yaw
        turned += (yaw - last + math.pi) % (2 * math.pi) - math.pi
        last = yaw
    assert turned == pytest.approx(4.0, rel=0.03)
    assert np.linalg.norm(sim.ground_truth().position[:2]) < 0.05


def expected_box_room_ranges(origin: np.ndarray, yaw: float, angles: np.ndarray, half: float = 2.0) -> np.ndarray:
    directions = yaw + angles
    c, s = np.cos(directions), np.sin(directions)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (half - origin[0]) / c, np.where(c < 0, (-half - origin[0]) / c, np.inf))
        ty = np.where(s > 0, (half - origin[1]) / s, np.where(s < 0, (-half - origin[1]) / s, np.inf))
    return np.minimum(tx, ty)


def test_scan_in_a_box_room_matches_analytic_distances():
    sim = make_sim(DATA / "box_room.sdf", SpawnPose(0.3, -0.2, 0.05, 0.4))
    run_for(sim, 0.5)
    (lidar,) = sim.lidars
    scan = sim.lidar_scan(0)
    site = sim.model.site("ppp_bot/lidar_frame").id
    origin = sim.data.site_xpos[site]
    heading = math.atan2(sim.data.site_xmat[site][3], sim.data.site_xmat[site][0])
    expected = expected_box_room_ranges(origin, heading, lidar.spec.angles())
    error = scan.ranges - expected
    sigma = lidar.spec.noise_stddev
    assert lidar.spec.samples == 640 and sigma == pytest.approx(0.01)
    assert np.all(np.abs(error) < 5 * sigma)
    assert abs(error.mean()) < 3 * sigma / math.sqrt(640)
    assert error.std() == pytest.approx(sigma, rel=0.2)


def test_noise_is_seeded():
    a, b, c = (make_sim(DATA / "box_room.sdf", seed=s) for s in (1, 1, 2))
    for sim in (a, b, c):
        run_for(sim, 0.2)
    assert np.array_equal(a.lidar_scan(0).ranges, b.lidar_scan(0).ranges)
    assert not np.array_equal(a.lidar_scan(0).ranges, c.lidar_scan(0).ranges)


def test_no_return_is_inf_and_too_close_is_minus_inf():
    spec = LidarSpec("l", "link", "frame", "scan", 10.0, 4, -1.0, 1.0, 0.08, 20.0, 0.0)
    ranges = finalize_ranges(np.array([-1.0, 0.05, 5.0, 25.0]), spec, np.random.default_rng(0))
    assert ranges.tolist() == [math.inf, -math.inf, 5.0, math.inf]
    sim = make_sim("empty")
    run_for(sim, 0.2)
    assert np.isposinf(sim.lidar_scan(0).ranges).all()


def test_imu_at_rest_feels_gravity_and_no_rotation():
    sim = make_sim("empty", SpawnPose(yaw=0.7))
    run_for(sim, 1.0)
    samples = []
    for _ in range(50):
        run_for(sim, 0.01)
        samples.append(sim.imu_sample(0).reading)
    accel = np.mean([s.linear_acceleration for s in samples], axis=0)
    gyro = np.mean([s.angular_velocity for s in samples], axis=0)
    np.testing.assert_allclose(accel, [0.0, 0.0, 9.81], atol=0.02)
    np.testing.assert_allclose(gyro, [0.0, 0.0, 0.0], atol=1e-3)
    x, y, z, w = samples[-1].orientation_xyzw
    assert 2 * math.atan2(z, w) == pytest.approx(0.7, abs=1e-3)


def test_wheel_commands_are_validated_and_clamped():
    sim = make_sim()
    with pytest.raises(KeyError, match="not a driven joint: caster"):
        sim.set_wheel_velocities({"caster": 1.0, "left_wheel_joint": 1.0})
    with pytest.raises(ValueError, match="non-finite velocity command: left_wheel_joint=nan"):
        sim.set_wheel_velocities({"left_wheel_joint": math.nan})
    sim.set_wheel_velocities({"left_wheel_joint": 50.0, "right_wheel_joint": -50.0})
    run_for(sim, 1.0)
    velocities = sim.wheel_state().velocities
    np.testing.assert_allclose(velocities, [10.0, -10.0], rtol=0.05)


def test_reset_puts_the_robot_back_and_time_goes_on():
    sim = make_sim(spawn=SpawnPose(1.0, 2.0, 0.05, 0.5))
    run_for(sim, 0.3)
    drive(sim, 0.4, 0.5)
    run_for(sim, 2.0)
    assert np.linalg.norm(sim.ground_truth().position[:2] - [1.0, 2.0]) > 0.5
    before = sim.time_s
    sim.reset_robot()
    truth = sim.ground_truth()
    np.testing.assert_allclose(truth.position, [1.0, 2.0, 0.05], atol=1e-9)
    assert truth.yaw == pytest.approx(0.5)
    assert np.allclose(truth.linear_velocity, 0) and sim.time_s == before
    run_for(sim, 0.5)  # wheels were stopped: it stays
    assert np.linalg.norm(sim.ground_truth().position[:2] - [1.0, 2.0]) < 0.01


def test_divergence_is_detected_and_the_runner_resets():
    sim = make_sim()
    run_for(sim, 0.1)
    sim.data.qvel[0] = math.nan  # MuJoCo resets itself on this (time too): still a divergence
    with pytest.raises(SimulationDiverged, match="diverged at t = 0.102"):
        sim.advance(1)
    messages: list[str] = []
    runner = PhysicsRunner(sim, log=messages.append)
    sim.reset_all()
    assert sim.time_s == pytest.approx(0.102)  # time never goes back
    sim.data.qvel[0] = 1e9
    assert runner.advance() == []
    assert "diverged" in messages[0] and "resetting" in messages[0]
    assert not sim.diverged() and np.isfinite(sim.ground_truth().position).all()
    assert sim.time_s >= 0.102


def test_bad_spawn_pose_and_unsupported_joint():
    with pytest.raises(SpawnError, match="spawn x = nan"):
        make_sim(spawn=SpawnPose(x=math.nan))
    floating = parse_urdf('<robot name="f"><link name="a"/><link name="b"><inertial><mass value="1"/>'
                          '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'
                          '<joint name="j" type="floating"><parent link="a"/><child link="b"/></joint></robot>')
    with pytest.raises(SpawnError, match="joint 'j' is floating"):
        make_sim(robot=floating)


def test_schedule_runs_events_at_their_rates():
    schedule = Schedule()
    fast, slow = Event(EventKind.JOINT_STATES), Event(EventKind.LIDAR, 0)
    schedule.add(fast, 100.0)
    schedule.add(slow, 10.0)
    counts = {fast: 0, slow: 0}
    t, dt = 0.0, 0.002
    while t < 1.0 - 1e-9:
        t += schedule.steps_to_next(t, dt, 1000) * dt
        for event in schedule.due(t, dt):
            counts[event] += 1
    # Each event is also due at t = 0 (a first reading at the start): 1 + 1 s × rate.
    assert counts == {fast: 101, slow: 11}
    with pytest.raises(ValueError, match="rate of 'imu1' must be a positive number"):
        schedule.add(Event(EventKind.IMU, 1), 0.0)


def test_schedule_stops_at_a_sync_time():
    schedule = Schedule()
    schedule.add(Event(EventKind.LIDAR, 0), 10.0, start_s=0.1)
    schedule.stop_at_s = 0.05
    assert schedule.steps_to_next(0.0, 0.001, 1000) == 50
    schedule.stop_at_s = None
    assert schedule.steps_to_next(0.0, 0.001, 1000) == 100
    # Sim time is a float sum of steps: a few picoseconds short of 23.2 s, the sync at 23.25 s is
    # still 25 steps of 2 ms away, not 26 (a sync 2 ms late puts timers restarted there off the grid).
    schedule = Schedule(stop_at_s=23.25)
    for time_s in (23.2 - 3e-11, 23.2, 23.2 + 3e-11):
        assert schedule.steps_to_next(time_s, 0.002, 1000) == 25
    assert schedule.steps_to_next(23.2, 0.002, 10) == 10
    assert schedule.steps_to_next(23.2491, 0.002, 1000) == 1  # less than a step: one, at or after it


def test_sensor_pose_in_the_tag_moves_the_sensor():
    """A lidar tag <pose> 0.1 m forward: the scan's origin moves with it."""
    urdf = re.sub(r'(<sensor name="laser" type="gpu_lidar">\s*)<pose>0 0 0 0 0 0</pose>',
                  r"\1<pose>0.1 0 0 0 0 0</pose>", process_xacro())
    assert "<pose>0.1 0 0 0 0 0</pose>" in urdf
    sim = make_sim(DATA / "box_room.sdf", robot=parse_urdf(urdf))
    mujoco.mj_forward(sim.model, sim.data)
    site = sim.model.site("ppp_bot/sensor/laser").id
    np.testing.assert_allclose(sim.data.site_xpos[site], [0.15, 0.0, 0.2], atol=1e-9)
    imu_site = sim.model.site("ppp_bot/sensor/imu").id
    np.testing.assert_allclose(sim.data.site_xpos[imu_site],
                               sim.data.site_xpos[sim.model.site("ppp_bot/imu_link").id], atol=1e-12)


# ------------------------------------------------------------ wheel slip
def wheel_travel(sim: Simulation, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """(reported, true) wheel rotation (rad) over ``seconds`` of driving, read at 100 Hz."""
    start_reported = sim.wheel_state().positions
    start_true = sim.data.qpos[sim._joint_qpos].copy()
    end = sim.time_s + seconds
    while sim.time_s < end - 1e-9:
        run_for(sim, 0.01)
        reported = sim.wheel_state().positions
    return reported - start_reported, sim.data.qpos[sim._joint_qpos] - start_true


def test_without_slip_encoders_report_the_true_rotation():
    sim = make_sim()
    drive(sim, 0.3, 0.2)
    reported, true = wheel_travel(sim, 2.0)
    np.testing.assert_array_equal(reported, true)


def test_slip_makes_wheels_disagree_reproducibly_with_the_seed():
    def travel(seed: int) -> tuple[np.ndarray, np.ndarray]:
        path = find_world("empty")
        spec, _ = load_world(path, model_paths(path))
        sim = Simulation(spec, ROBOT, seed=seed, slip=SlipModel(0.05, 1.0))
        drive(sim, 0.3, 0.0)
        return wheel_travel(sim, 5.0)

    (a, true_a), (b, _), (c, _) = travel(1), travel(1), travel(2)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    path = find_world("empty")
    names = Simulation(load_world(path, model_paths(path))[0], ROBOT).joint_names
    wheels = [names.index(j) for j in ("left_wheel_joint", "right_wheel_joint")]
    ratio = a[wheels] / true_a[wheels]
    # Each wheel's reported travel is off by a slip fraction of the order of the standard deviation.
    assert np.all(np.abs(ratio - 1.0) < 0.25)
    assert abs(ratio[0] - ratio[1]) > 1e-4


def test_slip_process_has_the_configured_spread_and_memory():
    slip = WheelSlip(SlipModel(0.03, 0.5), np.array([True, True]), np.random.default_rng(7))
    positions = np.zeros(2)
    slip.apply(0.0, positions, positions)
    samples = []
    for k in range(1, 40001):
        positions = positions + 0.1
        slip.apply(k * 0.01, positions, positions)
        samples.append(slip.slip[0])
    s = np.array(samples[1000:])
    assert abs(s.std() - 0.03) < 0.006
    lag = 50  # one correlation time at 10 ms
    correlation = np.corrcoef(s[:-lag], s[lag:])[0, 1]
    assert abs(correlation - math.exp(-1.0)) < 0.1


def test_slip_model_rejects_bad_settings():
    with pytest.raises(ValueError, match="in \\[0, 0.2\\], not nan"):
        SlipModel(float("nan"))
    with pytest.raises(ValueError, match="positive number of seconds, not 0"):
        SlipModel(0.01, 0.0)


# ------------------------------------------------------------ collisions
def test_driving_into_a_wall_is_one_collision_naming_it():
    sim = make_sim(DATA / "box_room.sdf")
    drive(sim, 0.4, 0.0)
    run_for(sim, 2.0)
    assert sim.take_collisions() == []  # the wheels and the caster on the ground are no collision
    run_for(sim, 6.0)  # reaches the east wall (inner face at x = 2.0) and pushes on
    collisions = sim.take_collisions()
    assert len(collisions) == 1
    assert collisions[0].obstacle.endswith("east")
    first = collisions[0]
    assert abs(first.position[0] - 2.0) < 0.05
    assert first.robot_part.startswith("ppp_bot/")
    run_for(sim, 1.0)  # still pressed against it: the same episode, nothing new
    assert sim.take_collisions() == []


def test_a_crash_into_a_corner_is_one_collision():
    sim = make_sim(DATA / "box_room.sdf", SpawnPose(1.0, 1.0, 0.05, math.pi / 4))
    drive(sim, 0.4, 0.0)
    run_for(sim, 6.0)
    collisions = sim.take_collisions()
    assert len(collisions) == 1
    assert collisions[0].obstacle.endswith(("east", "north"))
