"""A body that carries no plates reaching into the sand is said once a run (sim/sand_entry.py):
the sand does not act on it, so it passes through."""
import pytest

from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.sim.sand_entry import ENTRY_DEPTH

# a 1 kg plate on the sand carrying a 2 cm ball on a stalk, its lowest point `reach` m below
# the plate's underside
ROBOT = """<mujoco><worldbody>
  <body name="plate" pos="0 0 0.01"><freejoint/>
    <geom type="box" size="0.1 0.1 0.01" mass="1"/>
    <body name="probe" pos="0 0 {z}">
      <geom type="sphere" size="0.02" mass="0.01"/>
    </body>
  </body>
</worldbody></mujoco>"""


def _run(tmp_path, reach, bodies):
    path = tmp_path / 'robot.xml'
    path.write_text(ROBOT.format(z=-0.01 - reach + 0.02))
    lines = []
    summary = run_scene(load_scene(path, {'rft.sand_bodies': bodies, 'robot.spawn': 'model',
                                          'rft.plates_per_body': 100,
                                          'rft.other_bodies_density_per_mm2': None}),
                        duration=0.05, progress=False, plots=False, log=lines.append)
    return [line for line in lines if 'into the sand' in line], summary


@pytest.mark.parametrize('reach', [0.03, 0.1])
def test_a_body_without_plates_in_the_sand_is_said_once(tmp_path, reach):
    said, summary = _run(tmp_path, reach, ['plate'])
    assert len(said) == 1 and 'body probe reached' in said[0]
    depth_cm = float(said[0].split('reached ')[1].split(' cm')[0])
    assert depth_cm == pytest.approx(100 * reach, abs=0.5)  # (the plate sinks a little)
    assert said[0].endswith("name it a sand body (rft.sand_bodies; '*' takes every body) or give "
                            'the other bodies plates (rft.other_bodies_density_per_mm2)')
    assert said[0][len('warning: '):] in summary['notices']
    assert summary['outcome']['max_uncovered_sinkage_m'] == pytest.approx(reach, abs=0.005)


def test_nothing_is_said_of_a_body_within_the_margin_or_with_plates(tmp_path):
    assert _run(tmp_path, ENTRY_DEPTH / 2, ['plate'])[0] == []
    said, summary = _run(tmp_path, 0.1, ['plate', 'probe'])
    assert said == [] and summary['outcome']['max_uncovered_sinkage_m'] is None


def test_the_sand_is_read_under_a_bodys_lowest_corner_not_its_centre():
    """A 40 cm box turned with a 15 deg slope, 3 cm above it all along: its lowest corner
    lies 5 cm below the sand at its centre, but it is over lower ground there (downhill),
    so the box is not in the sand; lowered 5 cm, it is, 2 cm deep across the slope (2 /
    cos 15 deg vertically, as depth is measured)."""
    import mujoco
    import numpy as np

    from rft_sim_ros.sand.surface import Slope
    from rft_sim_ros.sim.sand_entry import SandEntryWatch
    slope = Slope(0.0, angle_deg=15.0)  # falling towards +x
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="chassis" pos="0 0 0.5"><freejoint/>'
        '<geom type="box" size="0.2 0.1 0.02"/></body></worldbody></mujoco>')
    data = mujoco.MjData(model)
    watch = SandEntryWatch(model, sand_bodies=[])
    tilt = np.radians(15.0)
    data.qpos[3:7] = [np.cos(tilt / 2), 0.0, np.sin(tilt / 2), 0.0]  # pitched with the slope
    for clearance, expected in ((0.03, None), (-0.02, 0.02 / np.cos(tilt))):
        data.qpos[2] = (0.02 + clearance) / np.cos(tilt)  # its underside `clearance` above
        mujoco.mj_kinematics(model, data)
        found = watch.deepest(data, slope)
        if expected is None:
            assert found is None
        else:
            assert found[0] == 'chassis' and found[1] == pytest.approx(expected, abs=1e-9)
