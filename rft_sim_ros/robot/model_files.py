"""The files a MuJoCo model (MJCF) is read from: the model file, the files it includes, and
the asset files it names (meshes, height fields, skins, textures), so that a study resumed
later can tell whether any of them changed (`study.spec.files_read`)."""
import functools
import xml.etree.ElementTree as ElementTree
from pathlib import Path

#: Attributes of an MJCF <texture> that name files (a cube or skybox may use six).
TEXTURE_FILES = ('file', 'fileback', 'filedown', 'filefront', 'fileleft', 'fileright',
                 'fileup')


@functools.lru_cache(maxsize=64)
def mjcf_files(model_path):
    """Absolute paths (sorted tuple) of the files the MJCF at `model_path` reads: itself, its
    <include>s (followed), and the asset files its elements name, each resolved as MuJoCo
    does (against the compiler's meshdir or texturedir, else the model's folder; an
    absolute path as it is). Files that do not exist are left out (the model's own load
    reports them); a file that is not readable XML gives just itself."""
    model_path = Path(model_path).resolve()
    folder = model_path.parent
    found, elements = set(), []
    _read(model_path, folder, found, elements)
    dirs = {'meshdir': '', 'texturedir': ''}
    for element in elements:
        if element.tag == 'compiler':
            asset = element.get('assetdir')
            for key in dirs:
                dirs[key] = element.get(key, asset if asset is not None else dirs[key])
    for element in elements:
        names = (TEXTURE_FILES if element.tag == 'texture' else ('file',)
                 if element.tag in ('mesh', 'hfield', 'skin') else ())
        base = folder / dirs['texturedir' if element.tag == 'texture' else 'meshdir']
        for attribute in names:
            name = element.get(attribute)
            if name:
                path = (base / name).resolve()
                if path.is_file():
                    found.add(str(path))
    return tuple(sorted(found))


def _read(path, folder, found, elements):
    """Add `path` to `found` and its elements (and its includes', relative to the main
    model's `folder`, as MuJoCo resolves them) to `elements`."""
    if str(path) in found or not path.is_file():
        return
    found.add(str(path))
    try:
        root = ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError):
        return
    for element in root.iter():
        if element.tag == 'include' and element.get('file'):
            _read((folder / element.get('file')).resolve(), folder, found, elements)
        else:
            elements.append(element)
