"""rft_sim_ros: walk robots through sand in simulation.

MuJoCo rigid-body dynamics coupled with 3D granular Resistive Force Theory (RFT).

Subpackages
-----------
rft  the force law and plate geometry (numpy; no MuJoCo, no ROS)
sim  MuJoCo coupling, scenes, the step loop, servo commands and gaits (no ROS)
ros  message building, the rosbag2 writer and the thin rclpy node
"""

__version__ = '0.1.0'
