"""Robot files for tests, written on demand (nothing large is committed).

`write_torque_quadruped(folder)`: a 12-DOF quadruped MJCF as vendors ship them: torque
`<motor>` actuators (+-33.5 N m), a `home` keyframe standing pose, collision primitives
(capsules, a sphere foot on each calf) and dense visual meshes (contype/conaffinity 0,
density 0): an ellipsoid shell of `trunk_subdivisions` icosphere levels on the trunk
(7: 327,680 triangles) and, with `thigh_subdivisions`, one on each thigh (6: 81,920 each).
15 kg in all; legs FL, FR, RL, RR with joints <leg>_hip_joint (abduction, x),
<leg>_thigh_joint and <leg>_calf_joint (pitch, y); feet 0.2 m below the knees.
"""
from pathlib import Path

import trimesh

HOME_THIGH, HOME_CALF = 0.8, -1.6  # rad; foot 0.279 m below the hip in the home pose
LEGS = {'FL': (0.18, 0.08), 'FR': (0.18, -0.08), 'RL': (-0.18, 0.08), 'RR': (-0.18, -0.08)}


def _shell(path, subdivisions, radii):
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    mesh.apply_scale(radii)
    mesh.export(path)
    return len(mesh.faces)


def write_torque_quadruped(folder, trunk_subdivisions=7, thigh_subdivisions=None):
    """Write quadruped.xml (+ its STL meshes) into `folder`; returns (path, visual triangles)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    triangles = _shell(folder / 'trunk_visual.obj', trunk_subdivisions, (0.22, 0.11, 0.06))
    assets = '<mesh name="trunk_visual" file="trunk_visual.obj"/>'
    thigh_visual = ''
    if thigh_subdivisions:
        triangles += 4 * _shell(folder / 'thigh_visual.stl', thigh_subdivisions,
                                (0.03, 0.03, 0.11))
        assets += '\n    <mesh name="thigh_visual" file="thigh_visual.stl"/>'
        thigh_visual = '<geom class="visual" type="mesh" mesh="thigh_visual" pos="0 0 -0.1"/>'
    legs, motors, home = [], [], []
    for leg, (x, y) in LEGS.items():
        side = 1 if y > 0 else -1
        legs.append(f"""
      <body name="{leg}_hip" pos="{x} {y} 0">
        <inertial pos="0 0 0" mass="0.5" diaginertia="4e-4 4e-4 4e-4"/>
        <joint name="{leg}_hip_joint" axis="1 0 0" range="-0.8 0.8"/>
        <geom class="collision" type="cylinder" size="0.04 0.02" zaxis="1 0 0"/>
        <body name="{leg}_thigh" pos="0 {side * 0.05} 0">
          <inertial pos="0 0 -0.1" mass="1.0" diaginertia="5e-3 5e-3 5e-4"/>
          <joint name="{leg}_thigh_joint" axis="0 1 0" range="-1.5 3.0"/>
          <geom class="collision" type="capsule" size="0.02" fromto="0 0 0 0 0 -0.2"/>
          {thigh_visual}
          <body name="{leg}_calf" pos="0 0 -0.2">
            <inertial pos="0 0 -0.1" mass="0.25" diaginertia="1.5e-3 1.5e-3 1e-4"/>
            <joint name="{leg}_calf_joint" axis="0 1 0" range="-2.7 -0.8"/>
            <geom class="collision" type="capsule" size="0.012" fromto="0 0 0 0 0 -0.18"/>
            <geom name="{leg}_foot" class="collision" type="sphere" size="0.022" pos="0 0 -0.2"/>
          </body>
        </body>
      </body>""")
        for joint in ('hip', 'thigh', 'calf'):
            motors.append(f'<motor name="{leg}_{joint}" joint="{leg}_{joint}_joint" '
                          'ctrlrange="-33.5 33.5"/>')
        home += ['0', str(HOME_THIGH), str(HOME_CALF)]
    xml = f"""<mujoco model="torque_quadruped">
  <compiler angle="radian"/>
  <option timestep="0.001"/>
  <default>
    <joint damping="0.1" armature="0.01"/>
    <default class="visual">
      <geom contype="0" conaffinity="0" group="2" density="0" rgba="0.3 0.3 0.35 1"/>
    </default>
    <default class="collision">
      <geom group="3" density="0"/>
    </default>
  </default>
  <asset>
    {assets}
  </asset>
  <worldbody>
    <body name="trunk" pos="0 0 0.35">
      <freejoint name="root"/>
      <inertial pos="0 0 0" mass="8" diaginertia="0.05 0.15 0.17"/>
      <geom class="collision" type="box" size="0.2 0.1 0.05"/>
      <geom class="visual" type="mesh" mesh="trunk_visual"/>{''.join(legs)}
    </body>
  </worldbody>
  <actuator>
    {chr(10).join('    ' + m for m in motors).strip()}
  </actuator>
  <keyframe>
    <key name="home" qpos="0 0 0.30 1 0 0 0 {' '.join(home)}"/>
  </keyframe>
</mujoco>
"""
    path = folder / 'quadruped.xml'
    path.write_text(xml)
    return path, triangles
