"""The implicit step compiled three times (`kernel_names.STEPS`): each variant calls
only the kernels of the parts it solves, the engine loads the one its model needs (and the
one that solves more where a model makes rows it did not foresee), the scene's notice checks
the variant its engine loads, and a cold start's second process compiles kernels the step
calls."""
import mujoco
import numpy as np
import pytest
from numba.core import ir, types
from numba.core.analysis import dead_branch_prune
from numba.core.compiler import run_frontend
from numba.core.ir_utils import simplify_CFG

from rft_sim_ros.kernel_names import STEP_PARTS, STEPS
from rft_sim_ros.prebuilt import dispatcher
from rft_sim_ros.sand import implicit_solve
from rft_sim_ros.sand.engine import SandEngine, can_collide, step_parts
from rft_sim_ros.sand.geoms import body_plates
from rft_sim_ros.scenes.config import bundled_scenes, load_scene
from rft_sim_ros.sim.simulation import Simulation, kernel_key

ROWS = {'add_matrix', 'constraint_start', 'constraint_terms', 'constraint_sets',
        'constraint_forces', 'add_row_forces'}
CONES = {'cone_start', 'cone_terms', 'cone_errors', 'cone_step', 'cone_settled',
         'cone_reports'}


def _called(function):
    """Names of the numba functions that `function` (a template bound by
    `implicit_solve._bound`) still calls once numba has pruned its branches on constants."""
    untyped = run_frontend(function)
    dead_branch_prune(untyped, (types.unknown,) * function.__code__.co_argcount)
    names = set()
    for block in simplify_CFG(untyped.blocks).values():
        names.update(statement.value.name for statement in block.body
                     if isinstance(statement, ir.Assign)
                     and isinstance(statement.value, ir.Global)
                     and hasattr(statement.value.value, 'py_func'))
    return names


@pytest.mark.parametrize('parts, absent, present', [
    ('plain', ROWS | CONES, set()), ('rows', CONES, ROWS), ('cones', set(), ROWS | CONES)])
def test_each_step_calls_the_kernels_of_its_parts_only(parts, absent, present):
    called = _called(dispatcher(STEPS[parts]).py_func)
    assert {'accumulate_slot', 'checked_solve', 'friction_terms'} <= called
    assert not called & absent and present <= called


@pytest.mark.parametrize('parts', STEP_PARTS)
def test_the_second_process_compiles_kernels_its_step_calls(parts):
    called = _called(dispatcher(STEPS[parts]).py_func)
    share = {kernel.py_func.__name__ for kernel, _ in implicit_solve.background_kernels(parts)}
    assert share and share <= called


def test_every_bundled_scene_loads_the_step_its_notice_checks():
    """`compile_notice` asks about the step `kernel_key` names before the model is built;
    the engine then loads that one: the plates and intruders without MuJoCo's rows, the
    robots with them, and a scene that keeps a rigid floor with them too."""
    loaded = {}
    for name, overrides in [*((name, {}) for name in bundled_scenes()),
                            ('plate_drop', {'sand.keep_floor': True})]:
        scene = load_scene(name, overrides)
        loaded[name] = Simulation(scene).engine._parts
        assert loaded[name] == kernel_key(scene)[3], (name, overrides)
    assert loaded['rotating_intruder'] == 'plain' and loaded['hexapod'] == 'rows'


DROP = """
<mujoco><option timestep="0.001" integrator="implicitfast" cone="{cone}"/>
<worldbody>
  <body name="box" pos="0 0 0.06"><freejoint/>
    <geom type="box" size="0.1 0.06 0.02" mass="2" contype="{box}" conaffinity="{box}"/>
  </body>
  <geom name="rock" type="box" pos="0.09 0 -0.05" size="0.04 0.04 0.05" contype="{rock}"
        conaffinity="{rock}"/>
</worldbody></mujoco>"""


def _drop(cone='pyramidal', rock=1, box=1):
    """(model, data, engine): a box dropped onto sand with a rigid rock under one end."""
    model = mujoco.MjModel.from_xml_string(DROP.format(cone=cone, rock=rock, box=box))
    data = mujoco.MjData(model)
    plates = {'box': body_plates(model, model.body('box').id, count=300)}
    return model, data, SandEngine(model, data, plates, zeta=3.75)


def test_a_model_that_can_make_no_row_loads_the_plain_step():
    assert step_parts(_drop(rock=0)[0]) == 'plain'
    two_geoms_one_body = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><freejoint/><geom size="0.1"/><geom pos="0.3 0 0" '
        'size="0.1"/></body></worldbody></mujoco>')  # (MuJoCo never collides them)
    assert not can_collide(two_geoms_one_body) and step_parts(two_geoms_one_body) == 'plain'
    assert step_parts(_drop(rock=0)[0], rows_expected=True) == 'rows'
    assert step_parts(_drop()[0]) == 'rows'
    assert step_parts(_drop(cone='elliptic')[0]) == 'cones'


@pytest.mark.parametrize('collidable, cone', [(False, 'pyramidal'), (True, 'elliptic')])
def test_rows_a_model_makes_later_load_the_step_that_solves_them(collidable, cone):
    """A model whose options change at run time (a rock made collidable, elliptic cones
    switched on) makes rows its loaded step does not solve: the engine loads the one that
    does at that step, and the box lands as with that step from the start."""
    model, data, engine = _drop(rock=int(collidable))
    first = engine._parts
    rock = model.geom('rock').id
    for field in ('geom_contype', 'geom_conaffinity'):  # (and its body's, MuJoCo's filter)
        getattr(model, field)[rock] = 1
        getattr(model, field.replace('geom', 'body'))[model.geom_bodyid[rock]] |= 1
    model.opt.cone = getattr(mujoco.mjtCone, f'mjCONE_{cone.upper()}')
    _, reference, right = _drop(cone=cone)
    assert right._parts != first
    for _ in range(400):
        engine.step()
        right.step()
    assert engine._parts == right._parts
    assert data.ncon > 0 and np.abs(data.qvel).max() < 0.05  # resting on the rock
    assert data.qpos == pytest.approx(reference.qpos, abs=1e-9)
