"""Writes the bipedal test robot: biped.xml and biped_spring_toes.xml (python make_biped.py).

A 0.9 m, 13 kg biped in MJCF: a box trunk on a free joint, two legs of hip roll and pitch,
knee, ankle pitch and roll, each with a position servo, on flat box feet; keyframe `stand`
(knees bent, feet flat under the hips, servos holding the pose), and `leaning`, the same
pose rolled LEAN_DEG about the walking direction (x), to push it over. The variant
biped_spring_toes.xml hinges a toe plate to the front of each foot on an unactuated joint
with a spring (stiffness 20 N m/rad, damping 0.2 N m s/rad), as walking robots' passive toes
are. Plain MuJoCo loads both; the test suite runs them in sand (test/test_biped.py).
"""
import math
from pathlib import Path

#: Knee bend of the standing keyframe (rad); hip and ankle pitch are -half of it, so the
#: feet stay flat under the hips.
KNEE = 0.6
#: Servo stiffness (N m/rad) and damping (N m s/rad): 13 kg on a 0.3 m lever sags ~0.1 rad.
KP, KV = 400.0, 8.0

#: deg: the roll of keyframe `leaning`, beyond what the feet can hold.
LEAN_DEG = 25.0

_LEG_JOINTS = ('hip_roll', 'hip_pitch', 'knee', 'ankle_pitch', 'ankle_roll')


def _leg(side, y, toes):
    toe = f'''
              <body name="{side}_toe" pos="0.1 0 0">
                <joint name="{side}_toe" axis="0 1 0" range="-0.8 0.8" stiffness="20"
                       damping="0.2"/>
                <geom name="{side}_toe" type="box" size="0.03 0.05 0.01" pos="0.03 0 -0.01"
                      mass="0.1"/>
              </body>''' if toes else ''
    return f'''
    <body name="{side}_thigh" pos="0 {y} -0.15">
      <joint name="{side}_hip_roll" axis="1 0 0" range="-0.5 0.5"/>
      <joint name="{side}_hip_pitch" axis="0 1 0" range="-1.5 1.0"/>
      <geom name="{side}_thigh" type="capsule" fromto="0 0 0 0 0 -0.28" size="0.04" mass="2"/>
      <body name="{side}_shin" pos="0 0 -0.28">
        <joint name="{side}_knee" axis="0 1 0" range="0 2.2"/>
        <geom name="{side}_shin" type="capsule" fromto="0 0 0 0 0 -0.23" size="0.035"
              mass="1.2"/>
        <body name="{side}_ankle" pos="0 0 -0.28">
          <joint name="{side}_ankle_pitch" axis="0 1 0" range="-1.0 1.0"/>
          <geom name="{side}_ankle" type="sphere" size="0.03" mass="0.2"/>
          <body name="{side}_foot" pos="0 0 -0.04">
            <joint name="{side}_ankle_roll" axis="1 0 0" range="-0.5 0.5"/>
            <geom name="{side}_foot" type="box" size="0.1 0.055 0.015" pos="0.02 0 -0.005"
                  mass="0.5"/>{toe}
          </body>
        </body>
      </body>
    </body>'''


def biped_xml(toes=False):
    """The MJCF text of the biped (with spring toes: `toes`)."""
    joints = [f'{side}_{joint}' for side in ('left', 'right') for joint in _LEG_JOINTS]
    stand = {'hip_pitch': -KNEE / 2, 'knee': KNEE, 'ankle_pitch': -KNEE / 2}
    pose = [stand.get(joint, 0.0) for side in ('left', 'right') for joint in _LEG_JOINTS]
    toe_pose = [0.0] if toes else []
    qpos = [pose[0:5] + toe_pose, pose[5:10] + toe_pose]
    height = 0.15 + (0.28 + 0.28) * math.cos(KNEE / 2) + 0.04 + 0.02
    servos = '\n'.join(f'    <position name="{j}" joint="{j}" kp="{KP:g}" kv="{KV:g}" '
                       f'ctrlrange="-2.2 2.2"/>' for j in joints)
    half = math.radians(LEAN_DEG) / 2
    stand_q, lean_q = (1, 0, 0, 0), (math.cos(half), math.sin(half), 0, 0)
    numbers = {name: ' '.join(f'{v:.6g}' for v in [0, 0, height, *q, *qpos[0], *qpos[1]])
               for name, q in (('stand', stand_q), ('leaning', lean_q))}
    controls = ' '.join(f'{v:.6g}' for v in pose)
    return f'''<mujoco model="biped{'_spring_toes' if toes else ''}">
  <!-- written by make_biped.py; {'with spring toes' if toes else 'no passive joints'} -->
  <compiler angle="radian"/>
  <option timestep="0.001" integrator="implicitfast"/>
  <default>
    <joint damping="0.5" armature="0.01"/>
    <geom contype="1" conaffinity="1" rgba="0.6 0.6 0.7 1"/>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="trunk" pos="0 0 {height:.6g}">
      <freejoint name="root"/>
      <geom name="trunk" type="box" size="0.1 0.15 0.15" pos="0 0 0.12" mass="4"/>
      <geom name="head" type="sphere" size="0.07" pos="0 0 0.35" mass="1"/>{_leg('left', 0.08, toes)}{_leg('right', -0.08, toes)}
    </body>
  </worldbody>
  <actuator>
{servos}
  </actuator>
  <keyframe>
    <key name="stand" qpos="{numbers['stand']}" ctrl="{controls}"/>
    <key name="leaning" qpos="{numbers['leaning']}" ctrl="{controls}"/>
  </keyframe>
</mujoco>
'''


if __name__ == '__main__':
    here = Path(__file__).parent
    (here / 'biped.xml').write_text(biped_xml())
    (here / 'biped_spring_toes.xml').write_text(biped_xml(toes=True))
