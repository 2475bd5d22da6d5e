"""`psrt view` with test hooks, run as a script: `python tests/view_hooks.py HOOK[,HOOK] -- VIEW ARGS`.

The hooks patch the viewer in this process only (nothing in viewer/ knows about them) to
make slow things happen on cue, so the window tests wait on conditions, never on how fast
the machine is:

- announce-render: print RENDERING on stdout once the first full-resolution tile is shown;
- hold-render: keep the render held after that tile (the worker's mid-render hold, never set);
- shot-first-tile: hold the render after its first full-resolution unit, grab the view to
  $PSRT_HOOK_SHOT once the window has drawn it, then let the render go on;
- hold-load: a scene load takes until the window has drawn HOLD_FRAMES frames showing it;
- block-load: a scene load never ends;
- cancel-load: once the window has drawn HOLD_FRAMES frames showing a load, its Cancel button
  is pressed (mouse events through ImGui, like a real click);
- hold-compile: a kernel compile takes until the window has drawn HOLD_FRAMES frames showing
  "compiling ...", for at least HOLD_SECONDS, doing Python work all along (as numba's compiler
  does, holding the GIL in turns); the window is grabbed to $PSRT_HOOK_SHOT meanwhile;
- hold-trace: the inspector's first (compiling) trace takes until the window has drawn
  HOLD_FRAMES frames showing "tracing pixel X,Y (compiling ...)", the same way;
- choose-ray: when the clicked pixel's ray tree arrives, its first shadow ray (else its first
  secondary ray) with a subdivision trace is chosen, as a click on its row would.
- stats-tab: the "Stats & output" tab is the selected one, so its panels are drawn every frame.

The load hooks apply to the file named by $PSRT_HOOK_FILE (a base name), or to every load.
If the window stopped drawing while it waits, the hold never ends and the run's --timeout
fails the test.
"""
from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

HOLD_FRAMES = 30
HOLD_SECONDS = 2.0

_frames = {"loading": 0, "compiling": 0, "tracing": 0}
_hooks = set()
_press = {"stage": 0, "pos": None}
_shot = {"taken": False}


def _count_frame(viewer) -> None:
    st = viewer.state
    if st.loading is not None and _hooked(st.loading[0]) and any(n.startswith("loading ") for n in st.notes):
        _frames["loading"] += 1
    if st.compiling is not None and any(n.startswith("compiling ") for n in st.notes):
        _frames["compiling"] += 1
    if st.inspecting is not None and any(n.startswith("tracing pixel") and "(compiling" in n for n in st.notes):
        _frames["tracing"] += 1
    if "announce-render" in _hooks and not _shot.get("announced"):
        r = st.render
        if r.phase == "full" and r.tiles_done >= 1:
            _shot["announced"] = True
            print("RENDERING", flush=True)


def _wait_frames(kind: str, seconds: float = 0.0, busy: bool = False) -> None:
    start, base = time.perf_counter(), _frames[kind]
    while _frames[kind] < base + HOLD_FRAMES or time.perf_counter() - start < seconds:
        if busy:
            sum(i * i for i in range(20000))  # Python work: the GIL changes hands as in a real compile
        else:
            time.sleep(0.01)


def _cancel_button_centre():
    """Window coordinates of the notes window's Cancel button (the end of its first line)."""
    from imgui_bundle import imgui
    win = imgui.internal.find_window_by_name("##viewport-notes")
    if win is None:
        return None
    style = imgui.get_style()
    width = imgui.calc_text_size("Cancel").x + 2 * style.frame_padding.x
    return (win.pos.x + win.size.x - style.window_padding.x - width / 2,
            win.pos.y + style.window_padding.y + imgui.get_text_line_height() / 2)


def _hooked(path: str) -> bool:
    """Whether the load hooks apply to `path` ($PSRT_HOOK_FILE, or every file)."""
    import os
    return os.environ.get("PSRT_HOOK_FILE", os.path.basename(path)) == os.path.basename(path)


def _inject(viewer) -> None:
    """Per frame, before ImGui's new frame: the Cancel button press, once loading was shown."""
    from imgui_bundle import imgui
    if "cancel-load" not in _hooks or _press["stage"] >= 4:
        return
    if _press["stage"] == 0:
        if _frames["loading"] < HOLD_FRAMES or not _hooked(viewer.state.loading[0]):
            return
        _press["pos"] = _cancel_button_centre()
        if _press["pos"] is None:
            return
    io = imgui.get_io()
    io.add_mouse_pos_event(*_press["pos"])
    if _press["stage"] in (1, 2):
        io.add_mouse_button_event(0, _press["stage"] == 1)
    _press["stage"] += 1


def install(hooks) -> None:
    _hooks.update(hooks)
    from viewer import app, loader, script
    import tracer.render

    frame = app.Viewer.frame

    def counted_frame(self, script_=None):
        if "hold-render" in _hooks and not _shot.get("held"):
            _shot["held"] = True
            self.worker.hold_mid_render()  # never set: the render stays after its first tile
        if "shot-first-tile" in _hooks and "first_tile" not in _shot:
            _shot["first_tile"] = self.worker.hold_mid_render()  # set once the view is grabbed
        frame(self, script_)
        _count_frame(self)

    app.Viewer.frame = counted_frame

    inject = script.Script.inject

    def hooked_inject(self, viewer):
        _inject(viewer)
        inject(self, viewer)

    script.Script.inject = hooked_inject

    after_draw = script.Script.after_draw

    def hooked_after_draw(self, viewer, fb_size):
        import os
        path = os.environ.get("PSRT_HOOK_SHOT")
        r = viewer.state.render
        if "shot-first-tile" in _hooks and not _shot["taken"] and r.phase == "full" and r.tiles_done >= 1:
            from viewer.outputs import write_png
            write_png(viewer.display.read_view(), path)  # drawn this frame, after the tile's upload
            _shot["taken"] = True
            _shot["first_tile"].set()
        if path and "hold-compile" in _hooks and not _shot["taken"] and _frames["compiling"] >= HOLD_FRAMES // 2:
            from viewer.outputs import write_png
            write_png(viewer.display.read_window(fb_size), path)
            _shot["taken"] = True
        after_draw(self, viewer, fb_size)

    script.Script.after_draw = hooked_after_draw

    read_scene = loader.read_scene
    never = threading.Event()

    def slow_read_scene(path, precision):
        if _hooked(path):
            if "block-load" in _hooks:
                never.wait()
            if "hold-load" in _hooks:
                _wait_frames("loading")
        return read_scene(path, precision)

    loader.read_scene = slow_read_scene

    compiled = tracer.render.compiled

    def held_compiled(kind, variant, args, on_compile=None):
        from tracer.variants import COMPILED
        if "hold-compile" not in _hooks or (kind, variant) in COMPILED or on_compile is None:
            return compiled(kind, variant, args, on_compile)
        start = time.perf_counter()
        on_compile(variant)
        _wait_frames("compiling", HOLD_SECONDS, busy=True)
        kernel = compiled(kind, variant, args)
        on_compile(variant, time.perf_counter() - start)
        return kernel

    tracer.render.compiled = held_compiled

    import tracer.trace_one
    trace_compiled = tracer.trace_one.compiled

    def held_trace_compiled(kind, variant, args, on_compile=None):
        from tracer.variants import COMPILED
        if "hold-trace" in _hooks and (kind, variant) not in COMPILED:
            _wait_frames("tracing", HOLD_SECONDS, busy=True)
        return trace_compiled(kind, variant, args, on_compile)

    tracer.trace_one.compiled = held_trace_compiled
    if "choose-ray" in _hooks:
        _install_choose_ray()


def _install_choose_ray() -> None:
    from viewer import interaction
    adopt = interaction.Interaction._adopt_tree

    def adopt_and_choose(self, job):
        adopt(self, job)
        ins = self.v.state.inspector
        if ins is None or ins.tree is None:
            return
        traced = [i for i, r in enumerate(ins.tree.rays) if i and r.steps is not None]
        shadow = [i for i in traced if ins.tree.rays[i].kind == "shadow"]
        if traced:
            ins.ray, ins.step = (shadow or traced)[0], -1
            self.update_outlines()

    interaction.Interaction._adopt_tree = adopt_and_choose

    if "stats-tab" in _hooks:
        from imgui_bundle import imgui
        begin_tab_item = imgui.begin_tab_item

        def stats_selected(label, p_open=None, flags=0):
            if label == "Stats & output":
                flags |= imgui.TabItemFlags_.set_selected
            return begin_tab_item(label, p_open, flags)

        app.imgui.begin_tab_item = stats_selected


def main(argv) -> int:
    hooks, sep, args = argv[0], argv[1], argv[2:]
    assert sep == "--", "usage: view_hooks.py HOOK[,HOOK] -- VIEW ARGS"
    install(h for h in hooks.split(",") if h)
    from viewer.cli_view import main as view_main
    return view_main(args, end_process=True)  # as `psrt view` does


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
