"""A small four-legged body, servoed hips and knees, standing in sand: the tests' case of a
robot at rest (`four_legs`), with the MJCF a test varies (joint friction, knee stops,
tendons and equalities, a load on it, a rigid rock under a foot) and its measure of rest
(`settle`)."""
import mujoco
import numpy as np

from rft_sim_ros.sand.engine import SandEngine
from rft_sim_ros.sand.geoms import body_plates

STANDING = """
<mujoco><option timestep="0.001" integrator="implicitfast" cone="{cone}" impratio="{impratio}"/>
<default><joint damping="0.1" frictionloss="{friction}" armature="0.01"/>
  <position kp="60" kv="1.5"/></default>
<worldbody>
  <body name="torso" pos="0 0 0.24"><freejoint/>
    <geom type="box" size="0.15 0.08 0.03" mass="4"/>
    {legs}
  </body>
  {world}
</worldbody>
{extra}
<actuator>{servos}</actuator></mujoco>"""
LEG = """<body name="thigh{i}" pos="{x} {y} 0"><joint name="hip{i}" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.015" mass="0.3"
            contype="0" conaffinity="0"/>
      <body name="shin{i}" pos="0 0 -0.1"><joint name="knee{i}" {knee} axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.012" mass="0.1"
              contype="0" conaffinity="0"/>
        <geom type="sphere" pos="0 0 -0.1" size="0.02" mass="0.05"/>
      </body></body>"""
#: (x, y) of the four hips on the torso, m.
CORNERS = ((0.12, 0.1), (0.12, -0.1), (-0.12, 0.1), (-0.12, -0.1))


def four_legs(friction=0.0, knee='', servos=('hip', 'knee'), world='', extra='',
              cone='pyramidal', impratio=1.0, override=False):
    """(model, data, SandEngine) of the body, 150 plates on each shin (foot included), zeta
    3.75. friction: every joint's frictionloss; knee: attributes of the knee joints (e.g. a
    range); servos: the joints with position servos; world: MJCF in the worldbody after the
    body (whose dofs stay first); extra: MJCF after the worldbody (tendons, equalities);
    cone, impratio: MuJoCo's friction cone and impratio; override: MuJoCo's solref/solimp
    override on, at the knees' own values."""
    legs = ''.join(LEG.format(i=i, x=x, y=y, knee=knee) for i, (x, y) in enumerate(CORNERS))
    actuators = ''.join(f'<position joint="{j}{i}"/>' for i in range(4) for j in servos)
    model = mujoco.MjModel.from_xml_string(STANDING.format(
        friction=friction, legs=legs, servos=actuators, world=world, extra=extra, cone=cone,
        impratio=impratio))
    if override:
        model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_OVERRIDE
        model.opt.o_solref, model.opt.o_solimp = model.jnt_solref[0], model.jnt_solimp[0]
    data = mujoco.MjData(model)
    plates = {f'shin{i}': body_plates(model, model.body(f'shin{i}').id, count=150)
              for i in range(4)}
    return model, data, SandEngine(model, data, plates, zeta=3.75)


def settle(data, engine, land=1500, watch=1000):
    """Steps to land and settle, then the watched steps' (solves, unsettled steps, largest
    torso speed m/s)."""
    for _ in range(land):
        engine.step()
    solves, unsettled, top = engine.solves, engine.unsettled_steps, 0.0
    for _ in range(watch):
        engine.step()
        top = max(top, np.linalg.norm(data.qvel[:3]))
    return engine.solves - solves, engine.unsettled_steps - unsettled, top
