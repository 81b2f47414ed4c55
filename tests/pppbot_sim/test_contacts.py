"""Contacts and saved worlds as Gazebo makes them: friction combined as ODE combines it (the
smaller mu and mu2 of two surfaces), a saved world's <state>, a robot put down on what lies
beneath it, and a robot that tips over reported. Each expectation says what Gazebo does."""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pppbot_common.upright import UprightWatch, posture, roll_pitch
from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import process_xacro
from pppbot_sim.contacts import Surface, combined, friction_priorities
from pppbot_sim.mj_build import SpawnPose
from pppbot_sim.sdf_world import read_sdf_world
from pppbot_sim.simulation import Simulation, load_world

URDF = process_xacro()
ROBOT = parse_urdf(URDF)
#: What Gazebo classic writes into a saved world's ground: mu 100, mu2 50, and every other surface default.
SAVED_GROUND = """<surface><friction><ode><mu>{mu}</mu><mu2>{mu2}</mu2></ode><torsional><ode/></torsional></friction>
  <contact><ode/></contact><bounce/></surface>"""


def world(tmp_path: Path, body: str, name: str = "w", version: str = "1.6") -> Path:
    path = tmp_path / f"{name}.world"
    path.write_text(f'<?xml version="1.0"?>\n<sdf version="{version}"><world name="{name}">\n'
                    '<physics type="ode"><max_step_size>0.001</max_step_size></physics>\n'
                    + textwrap.dedent(body) + "\n</world></sdf>\n")
    return path


def ground(mu: float = 1.0, mu2: float = 1.0) -> str:
    return ('<model name="ground_plane"><static>1</static><link name="link"><collision name="collision">'
            '<geometry><plane><normal>0 0 1</normal><size>100 100</size></plane></geometry>'
            + SAVED_GROUND.format(mu=mu, mu2=mu2) + "</collision></link></model>")


def sim_on(path: Path, spawn: SpawnPose = SpawnPose(z=math.nan), robot=ROBOT) -> Simulation:
    spec, loaded = load_world(path, [])
    return Simulation(spec, robot, spawn, world=loaded)


def tilt(sim: Simulation) -> float:
    return max(abs(a) for a in roll_pitch(*sim.ground_truth().orientation_xyzw))


def run(sim: Simulation, seconds: float, wheels: float = 0.0) -> None:
    end = sim.time_s + seconds
    while sim.time_s < end - 1e-9:
        if wheels:
            sim.set_wheel_velocities({"left_wheel_joint": wheels, "right_wheel_joint": wheels})
        sim.advance(10)


def test_odes_rule_the_smaller_friction_wins() -> None:
    assert combined(Surface(1.0, 1.0), Surface(100.0, 50.0)) == Surface(1.0, 1.0)
    assert combined(Surface(0.05, 0.05), Surface(1.0, 1.0)) == Surface(0.05, 0.05)
    # the smallest friction has the highest priority, so that MuJoCo gives a pair the smaller one
    priorities = friction_priorities([100.0, 1.0, 0.001, 1.0])
    assert priorities[0.001] > priorities[1.0] > priorities[100.0]


@pytest.mark.parametrize("x", [0.0, 5.0])
def test_ppp_bot_stands_on_a_mu_100_ground_and_drives_as_on_mu_1(tmp_path: Path, x: float) -> None:
    """Gazebo: the wheels' mu 1 against the ground's 100 gives 1; the caster's 0.001 gives 0.001. Before
    this rule, MuJoCo's larger-wins gave 100 and ppp_bot pitched past 0.9 rad within 0.2 s."""
    sticky = sim_on(world(tmp_path, ground(100, 50), "sticky"), SpawnPose(x, 0.0, math.nan))
    run(sticky, 3.0)
    assert tilt(sticky) < 0.01 and sticky.ground_truth().position[2] == pytest.approx(0.05, abs=0.002)
    plain = sim_on(world(tmp_path, ground(1, 1), "plain"), SpawnPose(x, 0.0, math.nan))
    run(plain, 3.0)
    for sim in (sticky, plain):
        run(sim, 4.0, wheels=10.0)  # 0.5 m/s for 4 s
    moved = [sim.ground_truth().position[:2] - (x, 0.0) for sim in (sticky, plain)]
    assert moved[1][0] == pytest.approx(2.0, abs=0.03)  # the reference: ppp_bot on ODE's default ground
    np.testing.assert_allclose(moved[0], moved[1], atol=0.01)  # straight, and as far, on the sticky ground
    assert tilt(sticky) < 0.05


def test_icy_ground_makes_the_wheels_slip(tmp_path: Path) -> None:
    """mu 0.05 (ice): the wheels (mu 1) get 0.05, about 0.5 m/s² of grip for a robot of ppp_bot's weight:
    0.5 m/s asked at once is not reached for a second, so 4 s cover well under the 2 m commanded, while
    the wheels turn as if they had gone the whole way (odometry over-reports, as Gazebo's would)."""
    sim = sim_on(world(tmp_path, ground(0.05, 0.05), "ice"))
    run(sim, 1.0)
    start = sim.ground_truth().position.copy()
    turned = np.array(sim.wheel_state().positions)
    run(sim, 4.0, wheels=10.0)
    moved = float(np.linalg.norm(sim.ground_truth().position[:2] - start[:2]))
    rolled = float(np.mean(np.array(sim.wheel_state().positions) - turned)) * 0.05
    assert moved < 0.85 * 2.0 and rolled > moved + 0.2


def test_unsimulated_surface_settings_are_named_once_and_defaults_are_not(tmp_path: Path) -> None:
    bouncy = ('<surface><bounce><restitution_coefficient>0.6</restitution_coefficient></bounce>'
              '<contact><ode><kp>100000</kp><kd>1</kd></ode></contact></surface>')
    boxes = "".join(f'<model name="b{i}"><static>1</static><pose>{i} 3 0.5 0 0 0</pose><link name="l">'
                    f'<collision name="c"><geometry><box><size>1 1 1</size></box></geometry>{bouncy}</collision>'
                    "</link></model>" for i in range(3))
    loaded = read_sdf_world(world(tmp_path, ground(100, 50) + boxes))
    assert len(loaded.warnings) == 2, loaded.warnings  # kd 1 is SDF's default: not named
    assert "<surface><bounce><restitution_coefficient> 0.6 of collision 'b0::l::c' is not simulated" in \
        loaded.warnings[0]
    assert "<surface><contact><ode><kp> 100000 of collision 'b0::l::c' is not simulated" in loaded.warnings[1]


def test_anisotropic_friction_and_urdf_contact_settings_are_named(tmp_path: Path) -> None:
    urdf = URDF.replace("</robot>", '<gazebo reference="left_wheel"><kp>100000</kp><selfCollide>true</selfCollide>'
                                    "</gazebo></robot>")
    sim = sim_on(world(tmp_path, ground(0.6, 0.2)), robot=parse_urdf(urdf))
    text = "\n".join(sim.warnings)
    assert "<gazebo reference='left_wheel'><kp> 100000 of robot 'ppp_bot' is not simulated" in text
    assert "<gazebo reference='left_wheel'><selfCollide> true of robot 'ppp_bot' is not simulated" in text
    assert ("friction of link 'chassis' (mu 1, mu2 1) on 'ground_plane::link::collision' (mu 0.6, mu2 0.2): Gazebo "
            "gives mu 0.6 along fdir1 and mu2 0.2 across; MuJoCo's friction is the same both ways, so pppbot uses "
            "0.2") in text
    # the pair's friction in MuJoCo is that smaller one
    ground_geom = sim.model.geom("ground_plane::link::collision").id
    wheel = sim.model.geom("ppp_bot/left_wheel::collision0").id
    assert sim.model.geom_priority[ground_geom] > sim.model.geom_priority[wheel]
    assert sim.model.geom_friction[ground_geom][0] == pytest.approx(0.2)


def test_a_saved_worlds_state_puts_models_links_and_joints_where_gazebo_did(tmp_path: Path) -> None:
    """The model blocks say where each model was when it was written; <state> where it was when the world
    was saved, which is where Gazebo classic puts it at load."""
    door = ('<model name="door"><link name="leaf"><pose>0 0.5 1 0 0 0</pose><inertial><mass>5</mass></inertial>'
            '<collision name="c"><geometry><box><size>0.05 1 2</size></box></geometry></collision></link>'
            '<joint name="hinge" type="revolute"><parent>world</parent><child>leaf</child><pose>0 -0.5 0 0 0 0</pose>'
            "<axis><xyz>0 0 1</xyz></axis></joint></model>")
    path = world(tmp_path, f"""\
        {ground()}
        <model name="shelf"><static>1</static><pose>1 0 0.5 0 0 0</pose><link name="l"><collision name="c">
          <geometry><box><size>1 0.2 1</size></box></geometry></collision></link></model>
        <model name="crate"><pose>0 5 0.25 0 0 0</pose><link name="l"><collision name="c">
          <geometry><box><size>0.5 0.5 0.5</size></box></geometry></collision></link></model>
        {door}
        <state world_name="w"><sim_time>412 0</sim_time>
          <model name="shelf"><pose>3 2 0.5 0 0 1.5707963</pose><scale>1 1 1</scale>
            <link name="l"><pose>3 2 0.5 0 0 1.5707963</pose><velocity>0 0 0 0 0 0</velocity></link></model>
          <model name="crate"><pose>-2 5 0.25 0 0 0</pose>
            <link name="l"><pose>-2 5 0.25 0 0 0</pose></link></model>
          <model name="door"><pose>0 0 0 0 0 0</pose><joint name="hinge"><angle axis="0">0.5</angle></joint>
            <link name="leaf"><pose>0.24 0.44 1 0 0 0.5</pose></link></model>
          <insertions><model name="late"/></insertions>
        </state>""")
    loaded = read_sdf_world(path)
    (shelf,) = [s for s in loaded.static_shapes if s.name.startswith("shelf")]
    np.testing.assert_allclose(shelf.pose[:3, 3], [3.0, 2.0, 0.5], atol=1e-9)
    np.testing.assert_allclose(shelf.pose[:3, 0], [0.0, 1.0, 0.0], atol=1e-6)  # turned 90°: its x is the world's y
    (crate,) = [b for b in loaded.bodies if b.name == "crate::l"]
    np.testing.assert_allclose(crate.pose[:3, 3], [-2.0, 5.0, 0.25])
    assert loaded.joint_positions == {"door::hinge": {0: 0.5}}
    assert any("<state><insertions> (models inserted while Gazebo ran) is not applied" in w for w in loaded.warnings)
    sim = sim_on(path)
    hinge = sim.model.joint("door::hinge")
    assert sim.data.qpos[hinge.qposadr[0]] == pytest.approx(0.5)
    # the leaf turned 0.5 rad about the hinge at (0, 0, 1): its centre (0, 0.5) goes to (-0.5 sin 0.5, 0.5 cos 0.5)
    np.testing.assert_allclose(sim.data.xpos[sim.model.body("door::leaf").id][:2],
                               [-0.5 * math.sin(0.5), 0.5 * math.cos(0.5)], atol=1e-6)


def test_spawned_without_a_height_the_robot_rests_on_what_is_beneath(tmp_path: Path) -> None:
    path = world(tmp_path, ground() + '<model name="stage"><static>1</static><pose>3 0 0.25 0 0 0</pose><link '
                 'name="l"><collision name="c"><geometry><box><size>2 2 0.5</size></box></geometry></collision>'
                 "</link></model>")
    on_floor = sim_on(path, SpawnPose(0.0, 0.0, math.nan))
    on_stage = sim_on(path, SpawnPose(3.0, 0.0, math.nan))
    assert (on_floor.spawn.z, on_stage.spawn.z) == pytest.approx((0.05, 0.55))
    run(on_stage, 1.0)
    assert on_stage.ground_truth().position[2] == pytest.approx(0.55, abs=0.002) and tilt(on_stage) < 0.01


def test_upright_watch_reports_each_tip_once() -> None:
    level = (0.0, 0.0, 0.0, 1.0)
    on_side = (math.sin(1.2), 0.0, 0.0, math.cos(1.2))  # rolled 2.4 rad
    watch = UprightWatch()
    assert watch.update(0.0, 0.05, level) is None and watch.upright
    tipped = watch.update(1.0, 0.05, on_side)
    assert tipped is not None and not tipped.upright and tipped.roll_rad == pytest.approx(2.4)
    assert tipped.describe() == "tipped over (beyond 0.5 rad) (roll 2.40 rad, pitch 0.00 rad, z 0.050 m, t = 1.00 s)"
    assert watch.update(1.1, 0.05, on_side) is None  # still on its side: said once
    assert watch.update(2.0, 0.05, level) is not None and watch.upright  # back on its wheels
    assert posture(0.0, -0.067, level).reason == "base below the ground (z under -0.02 m)"


def test_a_robot_driven_off_a_ledge_tips_over_and_is_seen(tmp_path: Path) -> None:
    """ppp_bot drives off a 0.5 m stage: it falls nose first, past 0.5 rad of pitch."""
    path = world(tmp_path, ground() + '<model name="stage"><static>1</static><pose>0 0 0.25 0 0 0</pose><link '
                 'name="l"><collision name="c"><geometry><box><size>2 2 0.5</size></box></geometry></collision>'
                 "</link></model>")
    sim = sim_on(path, SpawnPose(0.3, 0.0, math.nan))
    watch = UprightWatch()
    for _ in range(300):
        run(sim, 0.01, wheels=10.0)
        truth = sim.ground_truth()
        watch.update(sim.time_s, float(truth.position[2]), tuple(truth.orientation_xyzw.tolist()))
    assert watch.first_tip is not None and abs(watch.first_tip.pitch_rad) > 0.5
    assert watch.first_tip.stamp_s < 3.0
