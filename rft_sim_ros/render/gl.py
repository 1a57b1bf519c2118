"""Which OpenGL context renders offscreen, and one clear line when none can.

On a machine without a GPU or a display, MuJoCo renders through EGL over Mesa's software
rasteriser (llvmpipe); OSMesa is the fallback where EGL's libraries are missing. MUJOCO_GL
('egl', 'osmesa', 'glfw') chooses one explicitly, as for MuJoCo itself. PyOpenGL fixes its
platform at its first import, so the backend is chosen once per process (`backend`), before
anything imports OpenGL.

Debian/Ubuntu packages: EGL_PACKAGES for EGL over Mesa, OSMESA_PACKAGES for OSMesa (.ci/run
installs them when missing).
"""
import ctypes.util
import functools
import glob
import os

#: Debian packages for MuJoCo's EGL backend over Mesa's software renderer: the EGL and GL
#: dispatch libraries (glvnd), Mesa's EGL vendor library and its DRI drivers (llvmpipe).
EGL_PACKAGES = ('libegl1', 'libopengl0', 'libegl-mesa0', 'libgl1-mesa-dri')
#: Debian package for the OSMesa fallback.
OSMESA_PACKAGES = ('libosmesa6',)

_BACKENDS = ('egl', 'osmesa', 'glfw')


class RenderingUnavailable(ValueError):
    """No offscreen OpenGL context can be made here; the message says why and what to
    install, in one line."""


def _install_hint():
    return (f'apt-get install {" ".join(EGL_PACKAGES)} (EGL over Mesa), or '
            f'{" ".join(OSMESA_PACKAGES)} with MUJOCO_GL=osmesa')


def _egl_present():
    """Whether EGL's dispatch library and Mesa's EGL vendor are installed."""
    vendors = glob.glob('/usr/share/glvnd/egl_vendor.d/*.json') + glob.glob(
        '/etc/glvnd/egl_vendor.d/*.json')
    return bool(ctypes.util.find_library('EGL') and vendors and (
        ctypes.util.find_library('OpenGL') or ctypes.util.find_library('GL')))


def _osmesa_present():
    return bool(ctypes.util.find_library('OSMesa'))


@functools.lru_cache(maxsize=None)
def backend():
    """'egl', 'osmesa' or 'glfw': MUJOCO_GL where it names one of them (or PYOPENGL_PLATFORM
    'egl'/'osmesa' where set), else EGL where its libraries are installed, else OSMesa.
    Raises RenderingUnavailable when neither is installed or MUJOCO_GL names another."""
    asked = os.environ.get('MUJOCO_GL', '').strip().lower()
    platform = os.environ.get('PYOPENGL_PLATFORM', '').strip().lower()
    if asked:
        if asked not in _BACKENDS:
            raise RenderingUnavailable(f'cannot render: MUJOCO_GL={asked!r}; offscreen rendering '
                                       f'takes one of {", ".join(_BACKENDS)}')
        return asked
    if platform in ('egl', 'osmesa'):
        return platform
    if _egl_present():
        return 'egl'
    if _osmesa_present():
        return 'osmesa'
    raise RenderingUnavailable('cannot render: no EGL (libEGL with a Mesa vendor) and no '
                               f'OSMesa library on this machine: {_install_hint()}')


def offscreen_context(width, height):
    """A current OpenGL context (MuJoCo's GLContext of `backend()`) for a framebuffer of
    `width` x `height` pixels; free() it when done. Raises RenderingUnavailable saying why
    in one line."""
    name = backend()
    try:
        if name == 'egl':
            from mujoco.egl import GLContext
        elif name == 'osmesa':
            from mujoco.osmesa import GLContext
        else:
            from mujoco.glfw import GLContext
        context = GLContext(width, height)
        context.make_current()
    except Exception as error:  # (ImportError, EGL/OSMesa/GLFW errors of every kind)
        reason = ' '.join(str(error).split()) or type(error).__name__
        raise RenderingUnavailable(f'cannot render with MUJOCO_GL={name}: {reason[:200]}; '
                                   f'{_install_hint()}') from None
    return context


def check_offscreen():
    """Raise RenderingUnavailable (one line) unless an offscreen context can be made here;
    a run asked to record a video checks this before it starts."""
    offscreen_context(16, 16).free()


def offscreen_problem():
    """Why offscreen rendering cannot be done here (RenderingUnavailable's one line), or
    None where it can (`check_offscreen`)."""
    try:
        check_offscreen()
    except RenderingUnavailable as error:
        return str(error)
    return None
