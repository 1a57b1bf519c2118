"""auto's sand bodies and the legs where a branch forks below the base: a humanoid whose
legs hang by hip joints from a pelvis below its waist joint has two feet and two legs; a
shin's welded lower link beside its foot, and a foot's toes in the ground band, stay in
their leg; every body touching the ground (toes beside their sole, a snake's links) is a
sand body; a free body beside the robot with no sand body is named at start-up
and is held once named beside auto (robot/sand_bodies.py)."""
import mujoco
import pytest

from rft_sim_ros.robot.sand_bodies import auto_sand_bodies, legs_from_tree, other_bodies
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.simulation import Simulation

def _joint(name):
    return f'<joint name="{name}" type="hinge" axis="0 1 0"/>'


def _leg(side, y, toes, spur):
    foot = (f'<body name="toe_{side}_{k}" pos="0.08 {0.02 * k} 0">{_joint(f"toe_{side}_{k}")}'
            f'<geom type="sphere" size="0.02" pos="0 0 {-0.002 * (k + 2)}"/></body>'
            for k in (-1, 1)) if toes else ()
    # welded to the thigh, whose own geoms end above the ground band, and low
    spur_body = (f'<body name="spur_{side}" pos="0.1 0 -0.8">'
                 '<geom type="sphere" size="0.01"/></body>' if spur else '')
    return f"""
        <body name="thigh_{side}" pos="0 {y} -0.05">{_joint(f'hip_{side}')}
          <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.05"/>{spur_body}
          <body name="shin_{side}" pos="0 0 -0.4">{_joint(f'knee_{side}')}
            <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.04"/>
            <body name="foot_{side}" pos="0 0 -0.45">{_joint(f'ankle_{side}')}
              <geom type="box" size="0.1 0.04 0.02"/>{''.join(foot)}
            </body>
          </body>
        </body>"""


def _robot_body(toes=False, spur=False):
    return f"""
      <body name="torso" pos="0 0 1.4"><freejoint/>
        <geom type="capsule" fromto="0 -0.1 0 0 0.1 0" size="0.07"/>
        <body name="arm_right" pos="0 -0.2 0">{_joint('shoulder_right')}
          <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.04"/></body>
        <body name="arm_left" pos="0 0.2 0">{_joint('shoulder_left')}
          <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.04"/></body>
        <body name="waist" pos="0 0 -0.25">{_joint('waist')}
          <geom type="capsule" fromto="0 -0.06 0 0 0.06 0" size="0.06"/>
          <body name="pelvis" pos="0 0 -0.15">
            <geom type="capsule" fromto="0 -0.07 0 0 0.07 0" size="0.09"/>
            {_leg('right', -0.1, toes, spur)}{_leg('left', 0.1, toes, spur)}
          </body>
        </body>
      </body>"""


def _humanoid(toes=False, spur=False):
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><worldbody>{_robot_body(toes, spur)}</worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return model, data


def _names(model, ids):
    return sorted(model.body(b).name for b in ids)


@pytest.mark.parametrize('spur', [False, True], ids=['feet', 'feet_and_spurs'])
def test_legs_below_a_waist_give_two_feet_and_two_legs(spur):
    model, data = _humanoid(spur=spur)
    torso = model.body('torso').id
    feet = auto_sand_bodies(model, data, torso)
    assert _names(model, feet) == ['foot_left', 'foot_right']  # not the arms: above the band
    legs = legs_from_tree(model, [model.body(b).name for b in feet], torso)
    assert legs == {'thigh_right': ('foot_right',), 'thigh_left': ('foot_left',)}
    # the other bodies: those of a leg's branch join its wrench, before its foot (the leg's
    # point); the torso, waist, pelvis and arms are in no leg
    others = other_bodies(model, _names(model, feet))
    assert {'torso', 'arm_left', 'pelvis', 'shin_left'} <= set(others)
    legs = legs_from_tree(model, [model.body(b).name for b in feet], torso, others)
    spurs = ('spur_right',) if spur else ()
    assert legs == {'thigh_right': ('thigh_right', *spurs, 'shin_right', 'foot_right'),
                    'thigh_left': ('thigh_left', *(s.replace('right', 'left') for s in spurs),
                                   'shin_left', 'foot_left')}


def test_a_foots_toes_touching_the_ground_are_sand_bodies_of_its_leg():
    model, data = _humanoid(toes=True)
    torso = model.body('torso').id
    # the sole and both toes reach within 6 mm of the lowest point (the lower toe), within
    # AUTO_CONTACT of the robot's 1.4 m: all touch the ground, all in the foot's leg
    feet = auto_sand_bodies(model, data, torso)
    assert _names(model, feet) == ['foot_left', 'foot_right', 'toe_left_-1', 'toe_left_1',
                                   'toe_right_-1', 'toe_right_1']
    legs = legs_from_tree(model, [model.body(b).name for b in feet], torso)
    assert legs == {'thigh_right': ('foot_right', 'toe_right_-1', 'toe_right_1'),
                    'thigh_left': ('foot_left', 'toe_left_-1', 'toe_left_1')}
    # named toes are sand bodies of their own: the foot, not one of them, forks, so each toe
    # is a leg
    toes = ['toe_right_-1', 'toe_right_1']
    assert legs_from_tree(model, toes, torso) == {'toe_right__1': ('toe_right_-1',),
                                                   'toe_right_1': ('toe_right_1',)}


def _snake(links=8):
    """A chain of capsules lying flat, each hanging from the one before by a hinge."""
    body = ''
    for i in reversed(range(links)):
        joint = f'<joint name="j{i}" axis="0 0 1" range="-60 60"/>' if i else '<freejoint/>'
        body = (f'<body name="link{i}" pos="{"0 0 0.02" if i == 0 else "0.1 0 0"}">{joint}'
                '<geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.02" mass="0.1"/>'
                f'{body}</body>')
    servos = ''.join(f'<position joint="j{i}" kp="5"/>' for i in range(1, links))
    return f'<mujoco><worldbody>{body}</worldbody><actuator>{servos}</actuator></mujoco>'


def test_a_snake_lying_in_the_sand_is_held_by_every_link(tmp_path):
    """Its links hang from each other in one branch, all on the ground: auto picks each (one
    per branch left all but two to fall through the sand, and spawn rest never settled)."""
    path = tmp_path / 'snake.xml'
    path.write_text(_snake())
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 100}))
    assert sorted(sim.sand_bodies) == [f'link{i}' for i in range(8)]
    assert not [n for n in sim.notices if 'still moving' in n or 'bear the robot' in n]
    start = sim.data.qpos[:3].copy()
    sim.step(500)
    assert abs(sim.data.qvel).max() < 1e-3
    assert abs(sim.data.qpos[:3] - start).max() < 1e-4


def test_a_glob_takes_the_bodies_with_geoms_not_the_world_nor_empty_frames(tmp_path):
    """'*' makes the whole robot sand bodies (a robot that falls lands in the sand), not the
    world body (its floor) nor a frame without geoms, which a name still refuses."""
    frame = '<body name="imu_frame" pos="0 0 0.05"/>'
    robot = _robot_body().replace('<freejoint/>', '<freejoint/>' + frame, 1)
    path = tmp_path / 'robot.xml'
    path.write_text(f'<mujoco><worldbody><geom name="floor" type="plane" size="5 5 0.1"/>'
                    f'{robot}</worldbody></mujoco>')
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 20, 'rft.sand_bodies': ['*']}))
    shaped = [sim.model.body(b).name for b in range(1, sim.model.nbody)
              if sim.model.body_geomnum[b] > 0]
    assert list(sim.sand_bodies) == shaped and 'imu_frame' not in shaped
    with pytest.raises(SceneError, match="body 'imu_frame' has no geoms"):
        Simulation(load_scene(path, {'rft.plates_per_body': 20,
                                     'rft.sand_bodies': ['foot_*', 'imu_frame']}))


def test_free_bodies_the_sand_does_not_hold_are_named_at_start_up(tmp_path):
    """A loose crate beside the robot, with no sand body of its own, carries the other
    bodies' plates, and the sand holds it; with those off it falls through the sand: the
    user is told, and told how to change it (naming a sand body of it silences it)."""
    crate = ('<body name="crate" pos="1 0 0.2"><freejoint/>'
             '<geom type="box" size="0.1 0.1 0.1" mass="1"/></body>')
    path = tmp_path / 'robot_and_crate.xml'
    path.write_text(f'<mujoco><worldbody>{_robot_body()}{crate}</worldbody></mujoco>')
    held = Simulation(load_scene(path, {'rft.plates_per_body': 50}))
    assert 'crate' in held.other_bodies and not [n for n in held.notices if 'free bodies' in n]
    assert 'crate' not in {b for bodies in held.legs.values() for b in bodies}
    held.step(round(0.5 / held.timestep))
    assert 0.05 < held.data.xpos[held.model.body('crate').id, 2] < 0.1
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 50,
                                       'rft.other_bodies_density_per_mm2': None}))
    [notice] = [n for n in sim.notices if 'free bodies' in n]
    assert 'hold: crate;' in notice and '[auto, crate]' in notice
    both = Simulation(load_scene(path, {'rft.plates_per_body': 50,
                                        'rft.sand_bodies': ['foot_*', 'crate']}))
    assert not [n for n in both.notices if 'free bodies' in n]
    # auto beside a name: auto's picks for the robot, then the crate, a leg of its own
    beside = Simulation(load_scene(path, {'rft.plates_per_body': 50,
                                          'rft.sand_bodies': ['auto', 'crate'],
                                          'rft.other_bodies_density_per_mm2': None}))
    assert list(beside.sand_bodies) == [*sim.sand_bodies, 'crate']
    assert beside.legs == {**sim.legs, 'crate': ('crate',)}
    assert not [n for n in beside.notices if 'free bodies' in n]
    beside.step(round(0.5 / beside.timestep))                   # the sand holds the crate
    crate_z = beside.data.xpos[beside.model.body('crate').id, 2]
    assert 0.05 < crate_z < 0.1
    assert list(Simulation(load_scene(path, {
        'rft.plates_per_body': 50, 'rft.sand_bodies': 'crate, auto'})).sand_bodies) == \
        list(beside.sand_bodies)                                # auto's picks come first
    kept = Simulation(load_scene(path, {'rft.plates_per_body': 50, 'sand.keep_floor': True}))
    assert not [n for n in kept.notices if 'free bodies' in n]
