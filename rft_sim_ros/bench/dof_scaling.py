"""What the implicit solve costs against a robot's degrees of freedom: the same four-legged
body standing in sand (the same plates in the sand, 4 x 150 on its shins) with a passive
chain of N hinges hanging from its torso in the air (no plates, no contacts: degrees of
freedom only), stepped by the sand engine and, for reference, by MuJoCo alone on a rigid
floor. Process CPU time per step, the median of chunks; the sizes take turns chunk by chunk,
so that a loaded machine's noise hits them alike.

    python -m rft_sim_ros.bench.dof_scaling [N ...]
"""
import statistics
import sys
import time

import mujoco
import numpy as np

from ..sand.engine import SandEngine
from ..sand.geoms import body_plates
from ..sim.runner import machine_info
from .report import machine_line

#: Torso, four legs (hip and knee hinges, servoed), a chain of `links` passive hinges.
_BODY = """
<mujoco><option timestep="0.001" integrator="implicitfast"/>
<default><joint damping="0.1" armature="0.01"/><position kp="60" kv="1.5"/></default>
<worldbody>
  <geom name="floor" type="plane" size="2 2 0.1" contype="{floor}" conaffinity="{floor}"/>
  <body name="torso" pos="0 0 {height}"><freejoint/>
    <geom type="box" size="0.15 0.08 0.03" mass="4" contype="0" conaffinity="0"/>
    {legs}{chain}
  </body>
</worldbody>
<actuator>{servos}</actuator></mujoco>"""
_LEG = """<body name="thigh{i}" pos="{x} {y} 0"><joint name="hip{i}" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.015" mass="0.3" contype="0"
            conaffinity="0"/>
      <body name="shin{i}" pos="0 0 -0.1"><joint name="knee{i}" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.012" mass="0.1" contype="0"
              conaffinity="0"/>
        <geom type="sphere" pos="0 0 -0.1" size="0.02" mass="0.05" contype="{floor}"
              conaffinity="{floor}"/>
      </body></body>"""
_LINK = """<body pos="{x} 0 0"><joint axis="{axis}" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0.02 0 0" size="0.005" mass="0.01" contype="0"
            conaffinity="0"/>"""
_CORNERS = ((0.12, 0.1), (0.12, -0.1), (-0.12, 0.1), (-0.12, -0.1))


def body_with_chain(links, rigid=False):
    """(model, data) of the standing body with a chain of `links` passive hinges (nv = 14 +
    links); `rigid`: standing on a rigid floor (feet collide), for MuJoCo alone."""
    legs = ''.join(_LEG.format(i=i, x=x, y=y, floor=int(rigid))
                   for i, (x, y) in enumerate(_CORNERS))
    chain = ''.join(_LINK.format(x=0.16 if i == 0 else 0.02, axis='0 1 0' if i % 2 else '0 0 1')
                    for i in range(links)) + '</body>' * links
    servos = ''.join(f'<position joint="{joint}{i}"/>' for i in range(4)
                     for joint in ('hip', 'knee'))
    model = mujoco.MjModel.from_xml_string(_BODY.format(
        legs=legs, chain=chain, servos=servos, floor=int(rigid),
        height=0.22 if rigid else 0.24))
    return model, mujoco.MjData(model)


def _cases(links):
    """{links: (step function, data)}: the sand engine's step and MuJoCo's rigid step."""
    cases = {}
    for n in links:
        model, data = body_with_chain(n)
        plates = {f'shin{i}': body_plates(model, model.body(f'shin{i}').id, count=150)
                  for i in range(4)}
        engine = SandEngine(model, data, plates, zeta=3.75)
        rigid_model, rigid_data = body_with_chain(n, rigid=True)
        cases[n] = (engine.step, data,
                    lambda m=rigid_model, d=rigid_data: mujoco.mj_step(m, d), rigid_data)
    return cases


def dof_scaling(links=(0, 8, 16, 32, 64), chunks=7, chunk_steps=500, settle_steps=1500):
    """[{links, nv, sand_step_s, rigid_step_s, plates_in_sand}]: CPU seconds per step
    (medians over `chunks` of `chunk_steps`, after `settle_steps`) of the body with each
    chain length, with the sand engine and with MuJoCo alone."""
    cases = _cases(links)
    for step, _, rigid, _ in cases.values():
        for _ in range(settle_steps):
            step()
            rigid()
    times = {n: ([], []) for n in links}
    for _ in range(chunks):
        for n, (step, _, rigid, _) in cases.items():
            for index, function in enumerate((step, rigid)):
                started = time.process_time()
                for _ in range(chunk_steps):
                    function()
                times[n][index].append((time.process_time() - started) / chunk_steps)
    rows = []
    for n, (step, data, _, _) in cases.items():
        engine = step.__self__
        rows.append({'links': n, 'nv': int(data.qvel.shape[0]),
                     'sand_step_s': statistics.median(times[n][0]),
                     'rigid_step_s': statistics.median(times[n][1]),
                     'plates_in_sand': int(engine.active_plates()[2].shape[0]),
                     'standing': bool(np.isfinite(data.qpos).all()
                                      and data.qpos[2] > 0.05)})
    return rows


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    links = tuple(int(value) for value in argv) or (0, 8, 16, 32, 64)
    rows = dof_scaling(links)
    print(machine_line(machine_info()))
    print('| chain hinges | nv | plates in sand | sand engine step (us) | rigid mj_step (us) |')
    print('|---|---|---|---|---|')
    for row in rows:
        print(f'| {row["links"]} | {row["nv"]} | {row["plates_in_sand"]} | '
              f'{row["sand_step_s"] * 1e6:.1f} | {row["rigid_step_s"] * 1e6:.1f} |')


if __name__ == '__main__':
    main()
