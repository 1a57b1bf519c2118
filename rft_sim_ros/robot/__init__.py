"""Robot descriptions in: MJCF, URDF and xacro files (or a `robot_description` string) into
a MuJoCo model specification plus what the joints need (limits, initial positions).

`load_description` is the one entry point; `packages` resolves `$(find pkg)`,
`package://` and `file://`; `xacro_files` expands xacro; `urdf` turns URDF into what
MuJoCo's URDF importer reads; `meshes` converts collision meshes MuJoCo cannot read.
"""
from .description import DescriptionError, RobotDescription, load_description  # noqa: F401
