"""ament_python / pip build script for rft_sim_ros.

The same file serves `colcon build` (ROS 2) and `pip install .` (no ROS): scenes, models and
launch files go to share/rft_sim_ros, where `rft_sim_ros.resources` finds them in both cases.
"""
import os
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'rft_sim_ros'


def share_tree(folder):
    """data_files entries that install `folder` (recursively) under share/rft_sim_ros."""
    entries = {}
    for path in glob(os.path.join(folder, '**', '*'), recursive=True):
        if os.path.isfile(path):
            target = os.path.join('share', PACKAGE, os.path.dirname(path))
            entries.setdefault(target, []).append(path)
    return sorted(entries.items())


setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        *share_tree('config'),
        *share_tree('models'),
        *share_tree('launch'),
    ],
    python_requires='>=3.10',
    install_requires=[
        'numpy>=1.24',
        'mujoco>=3.3',
        'trimesh>=4.0',
        'pyyaml>=6.0',
        'numba>=0.59',
        # numba's ahead-of-time compiler (numba.pycc: `rft-sim warmup` builds the engine's
        # kernels for this CPU, rft_sim_ros/prebuild.py) compiles and links with setuptools,
        # which a Python 3.12 virtual environment no longer has
        'setuptools>=64',
        'rosbags>=0.10',
        'matplotlib>=3.7',
        # PNG height fields and zeta maps read exactly at every bit depth (sand/grid_files.py;
        # matplotlib's imread mis-scales 2- and 4-bit greys); matplotlib needs it anyway
        'pillow>=9.0',
        'scipy>=1.10',      # trimesh's optional mesh operations (hulls, repairs) on users' meshes
        'xacro>=2.0',       # ROS's xacro, from PyPI: robot descriptions without ROS
        'pycollada>=0.8',   # COLLADA (.dae) collision meshes, converted by trimesh
        # trimesh's quadric decimation: a mesh far finer than its plate count is simplified
        # to it (sand/geoms.py), in C++ (~1 s for 300k triangles, then cached)
        'fast-simplification>=0.1',
        # ruamel.yaml's C emitter (ruamel.yaml comes with rosbags): a bag's metadata is
        # written in 3 ms instead of 12 (2 % of the hexapod's main job), with long values on
        # one line as rosbag2 writes them; without it rosbags falls back to pure Python
        'ruamel.yaml.clib>=0.2',
        # videos of runs (rft-sim run --video, rft-sim render): PyAV encodes H.264 in-process
        # with the libx264 its wheels ship. Chosen over imageio-ffmpeg, which pipes frames
        # into an ffmpeg child process: a Ctrl-C reaches that child too and kills it before
        # the file is finished, while in-process the run's own interrupt handling closes it
        # (and PyAV decodes, which the tests use to check the files)
        'av>=12.0',
    ],
    extras_require={
        # Ray: studies on a cluster (`rft-sim sweep --ray`); the test extra includes it so
        # CI tests that backend on a real single-machine cluster
        'ray': ['ray>=2.9'],
        'test': ['pytest>=7', 'hypothesis>=6.80', 'ray>=2.9'],
    },
    zip_safe=False,
    maintainer='rft_sim_ros developers',
    maintainer_email='dev@rft-sim-ros.invalid',
    description='MuJoCo + 3D granular Resistive Force Theory sand simulation for ROS 2.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'rft-sim = rft_sim_ros.__main__:main',
            'sim = rft_sim_ros.ros.node:main',
            'tripod_gait = rft_sim_ros.ros.gait_node:main',
            'trot_gait = rft_sim_ros.ros.trot_gait_node:main',
        ],
    },
)
