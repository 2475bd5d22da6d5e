"""Opening a scene file into the viewer state; a file that fails leaves the previous scene."""
from __future__ import annotations

import os

from tracer.camera import view_of
from tracer.errors import SceneError
from tracer.geometry import prepare
from tracer.scene import load_scene


def open_scene(state, geometry, path) -> bool:
    """Load, prepare and view `path`; on any failure log the error and keep the current scene."""
    path = os.fspath(path)
    try:
        scene = load_scene(path)
        geom = prepare(scene, state.opts.precision)  # fails early on what the kernel cannot trace
        home = view_of(scene)
        home.basis()  # a degenerate camera is an error now, not in the worker
    except (SceneError, ValueError, OSError) as e:
        where = "" if path in str(e) else f"{path}: "  # SceneError already names the file
        state.log(f"cannot open {where}{e}" + ("; keeping the current scene" if state.scene else ""), "error")
        return False
    except Exception as e:  # a loader bug must not take the window down either
        state.log(f"cannot open {path}: {type(e).__name__}: {e}", "error")
        return False
    geometry.adopt(scene, state.opts.precision, geom)
    state.scene, state.scene_path = scene, os.path.abspath(path)
    state.home_view = state.view = home
    state.inspector = None
    state.render.key = None
    state.error = None
    state.add_recent(path)
    state.log(f"opened {path}: {scene.n_patches} patches")
    return True
