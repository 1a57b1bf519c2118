"""rft_sim_ros: walk robots through sand in simulation.

MuJoCo rigid-body dynamics coupled with 3D granular Resistive Force Theory (RFT).

Subpackages (each imports only those listed before it; docs/code.md has the top-level
modules too)
-----------
rft         the force law and plate geometry (numpy; no MuJoCo, no ROS)
sand        the sand engine: plates from MuJoCo geoms, surfaces, compiled coupling, the step
robot       robot descriptions (MJCF, URDF, xacro) and ros2_control-like joint interfaces
control     servo commands: trajectories, positions and efforts, validated
scenes      scene files (schema, config) and the paper's scenarios, robots and gaits
sim         the simulation loop, runner, state, time series, summary, plots and the run's
            page, report.html (no ROS)
render      offscreen frames and videos of a run, and the live viewer
ros         message building, the rosbag2 writer and reader, a run's video made again from
            its bag, and the thin rclpy nodes
study       parameter sweeps on local processes or a Ray cluster
validation, bench   `rft-sim validate` and `rft-sim bench`
"""

__version__ = '0.1.0'
