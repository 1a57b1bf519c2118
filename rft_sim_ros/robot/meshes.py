"""Mesh files MuJoCo cannot read, made readable: converted with trimesh to binary STL; and the
notice of the visual meshes a description drops (`dropped_visuals_notice`).

MuJoCo reads STL, OBJ and MSH meshes. Collision meshes in other formats (COLLADA .dae, PLY,
glTF, OFF, ...) are loaded with trimesh (COLLADA through pycollada) and handed to MuJoCo
as in-memory STL assets, in the file's own units (URDF meshes are in metres, as REP 103
asks; a <mesh scale> still applies).
"""
import logging
from pathlib import Path

#: Mesh file suffixes MuJoCo's own loader reads.
MUJOCO_MESH_SUFFIXES = frozenset({'.stl', '.obj', '.msh'})


class MeshError(ValueError):
    """A collision mesh can be neither read by MuJoCo nor converted; names the file."""


def mujoco_reads(path):
    """Whether MuJoCo loads mesh file `path` itself (by its suffix)."""
    return Path(path).suffix.lower() in MUJOCO_MESH_SUFFIXES


def converted_stl(path):
    """Binary STL bytes of the mesh in `path` (all its parts in one triangle mesh, the
    file's scene transforms applied); raises MeshError naming the file."""
    import trimesh  # (here: ~0.5 s to import, and only such meshes need it)
    trimesh_log = logging.getLogger('trimesh')
    level = trimesh_log.level
    trimesh_log.setLevel(logging.ERROR)  # its fallbacks (e.g. dense normals) are not errors
    try:
        loaded = trimesh.load(str(path), force='mesh', process=False)
    except Exception as error:  # trimesh raises many kinds for unreadable files
        raise MeshError(f'collision mesh {path}: MuJoCo cannot read {Path(path).suffix} '
                        f'and trimesh could not convert it: {error}') from None
    finally:
        trimesh_log.setLevel(level)
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshError(f'collision mesh {path}: no triangles found to convert')
    return loaded.export(file_type='stl')


def dropped_visuals_notice(where, dropped):
    """The notice of visual meshes dropped from a description (URDF or MJCF): `dropped`,
    one text a mesh."""
    return (f'{where}: dropped {len(dropped)} visual mesh(es) MuJoCo cannot read (MuJoCo does '
            'not collide visuals; with rft.plate_geoms: visual their bodies keep their '
            f'collision geoms): {", ".join(sorted(set(dropped)))}')
