"""The command interfaces a URDF's `<ros2_control>` block declares per joint.

ros2_control's topic hardware interfaces pack their JointState commands by these
declarations (`rft_sim_ros.control.joint_state_commands`), so reading a robot with mixed
interfaces needs them. ROS-free; works on the parsed <robot> element.
"""


def command_interfaces(root):
    """{joint: (interface names, in the block's order)} of every joint of every
    `<ros2_control>` element under URDF <robot> element `root`; {} when it has none."""
    declared = {}
    for control in root.iter('ros2_control'):
        for joint in control.findall('joint'):
            names = tuple(i.get('name') for i in joint.findall('command_interface')
                          if i.get('name'))
            if joint.get('name'):
                declared[joint.get('name')] = names
    return declared
