"""GPU side of the viewer: float textures of the traced image, programs from `shaders/`.

The image is composed at image resolution into an offscreen framebuffer (the "view":
tone-mapped colour, overlay, box outlines), which is then copied into its window region.
Screenshots read the view, so they hold exactly the traced pixels plus overlays.
"""
from __future__ import annotations

import os
from pathlib import Path

import moderngl
import numpy as np

SHADER_DIR = Path(os.environ.get("PSRT_SHADER_DIR", Path(__file__).resolve().parent.parent / "shaders"))
PROGRAMS = {"image": ("fullscreen.vert", "image.frag"),
            "blit": ("fullscreen.vert", "blit.frag"),
            "boxes": ("boxes.vert", "boxes.frag")}
TONE_CODE = {"clamp": 0, "reinhard": 1}
IMAGE_SWITCHES = ("TONE", "OVERLAY", "LOG_SCALE")
MAX_SPECIALS = 4


class ShaderError(RuntimeError):
    """A shader file is missing or failed to compile/link; the message holds the log."""


def read_sources(directory: Path = SHADER_DIR) -> dict:
    """{file name: GLSL text} of every shader file PROGRAMS needs; ShaderError names a missing one."""
    sources = {}
    for files in PROGRAMS.values():
        for f in files:
            path = Path(directory) / f
            try:
                sources[f] = path.read_text()
            except OSError as e:
                raise ShaderError(f"shader {path}: cannot read ({e.strerror or e})") from None
    return sources


def with_defines(source: str, defines) -> str:
    """The source with `#define NAME` lines inserted after its #version line."""
    head, _, rest = source.partition("\n")
    return head + "\n" + "".join(f"#define {d}\n" for d in defines) + rest


def compile_program(ctx, sources: dict, name: str, defines=(), directory=SHADER_DIR):
    vert, frag = PROGRAMS[name]
    try:
        return ctx.program(vertex_shader=with_defines(sources[vert], defines),
                           fragment_shader=with_defines(sources[frag], defines))
    except Exception as e:  # moderngl.Error carries the driver's compile/link log
        label = f"{vert} + {frag}" + (f" with {', '.join(defines)}" if defines else "")
        raise ShaderError(f"shader program {name!r} ({label} in {directory}):\n{e}") from None


def _set(prog, name, value):
    if name in prog:  # the GLSL compiler drops unused uniforms
        prog[name].value = value


def view_projection(view, width: int, height: int) -> np.ndarray:
    """The 4x4 matrix (column-major bytes order) matching tracer.camera.primary_rays."""
    forward, right, up = view.basis()
    eye = np.asarray(view.eye, float)
    rot = np.stack([right, up, -forward])
    look = np.eye(4)
    look[:3, :3] = rot
    look[:3, 3] = -rot @ eye
    dist = float(np.linalg.norm(np.asarray(view.look_at, float) - eye))
    near, far = 1e-4 * dist, 1e4 * dist
    f = 1.0 / np.tan(np.radians(view.fov_deg) / 2.0)
    proj = np.zeros((4, 4))
    proj[0, 0] = f * height / width
    proj[1, 1] = f
    proj[2, 2] = (far + near) / (near - far)
    proj[2, 3] = 2 * far * near / (near - far)
    proj[3, 2] = -1.0
    return proj @ look


class Display:
    """Textures and programs; every method is called from the UI thread only."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.programs = {}
        self.sources = {}
        self.shader_dir = SHADER_DIR
        self.vaos = {}
        self.error = None
        self.generation = 0   # bumped by every change of the image textures
        self.composed = None  # what the view framebuffer holds, to skip redrawing it
        self.size = (0, 0)
        self.colour = self.data = self.view_tex = self.fbo = None
        self.lut = ctx.texture((256, 1), 3, dtype="f4")
        self.lut.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.lut.repeat_x = self.lut.repeat_y = False
        self.lut_name = None
        self.box_vbo = self.box_vao = None
        self.box_count = 0
        self.reload_shaders()

    # --- programs -------------------------------------------------------------------------
    def reload_shaders(self, directory: Path = SHADER_DIR) -> bool:
        """(Re)compile the shaders; on failure keep the old ones and record the log in .error.

        Every image variant's code is compiled once here (all switches on, and all off), so a
        broken shader is reported at start, not when an overlay is first shown.
        """
        try:
            sources = read_sources(directory)
            programs = {(name, ()): compile_program(self.ctx, sources, name, (), directory) for name in PROGRAMS}
            full = tuple(IMAGE_SWITCHES)
            programs[("image", full)] = compile_program(self.ctx, sources, "image", full, directory)
        except ShaderError as e:
            self.error = str(e)
            return False
        for p in self.programs.values():
            if p is not None:
                p.release()
        self.programs, self.sources, self.shader_dir = programs, sources, directory
        self.vaos = {}
        self.set_boxes(None)
        self.error = None
        self.composed = None
        return True

    def program(self, name: str, defines=()):
        """A compiled program variant (cached); None if it does not compile."""
        key = (name, tuple(defines))
        if key not in self.programs:
            try:
                self.programs[key] = compile_program(self.ctx, self.sources, name, key[1], self.shader_dir)
            except ShaderError as e:
                self.error = str(e)
                self.programs[key] = None  # do not retry every frame; reload_shaders clears it
        return self.programs[key]

    def _vao(self, prog):
        if prog.glo not in self.vaos:
            self.vaos[prog.glo] = self.ctx.vertex_array(prog, [])
        return self.vaos[prog.glo]

    # --- textures -------------------------------------------------------------------------
    def resize(self, width: int, height: int) -> None:
        """(Re)allocate the image textures and the view framebuffer for a new image size."""
        if (width, height) == self.size:
            return
        for obj in (self.colour, self.data, self.fbo, self.view_tex):
            if obj is not None:
                obj.release()
        self.size = (width, height)
        self.colour = self.ctx.texture((width, height), 3, dtype="f4")
        self.data = self.ctx.texture((width, height), 2, dtype="f4")
        self.view_tex = self.ctx.texture((width, height), 4)
        for t in (self.colour, self.data, self.view_tex):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
        self.fbo = self.ctx.framebuffer(color_attachments=[self.view_tex])
        self.composed = None
        self.clear_image()

    def clear_image(self) -> None:
        w, h = self.size
        self.colour.write(np.zeros((h, w, 3), np.float32))
        blank = np.zeros((h, w, 2), np.float32)
        blank[..., 0] = np.nan
        self.data.write(blank)
        self.generation += 1

    def upload(self, colour: np.ndarray | None, data: np.ndarray | None, rect=None) -> None:
        """Write full-size (H, W, c) arrays, or only their tile rect (y0, y1, x0, x1)."""
        w, h = self.size
        y0, y1, x0, x1 = rect if rect is not None else (0, h, 0, w)
        if y1 <= y0 or x1 <= x0:
            return
        viewport = (x0, y0, x1 - x0, y1 - y0)
        self.generation += 1
        if colour is not None:
            self.colour.write(np.ascontiguousarray(colour[y0:y1, x0:x1], np.float32), viewport=viewport)
        if data is not None:
            self.data.write(np.ascontiguousarray(data[y0:y1, x0:x1], np.float32), viewport=viewport)

    def set_colormap(self, name: str, table: np.ndarray) -> None:
        if name != self.lut_name:
            self.lut.write(np.ascontiguousarray(table, np.float32).reshape(1, 256, 3))
            self.lut_name = name
            self.generation += 1

    def set_boxes(self, vertices: np.ndarray | None) -> None:
        """Box outline line segments: (n, 7) float32 rows of x y z r g b a, two rows a segment."""
        if self.box_vbo is not None:
            self.box_vbo.release()
            self.box_vbo = self.box_vao = None
        self.box_count = 0
        self.generation += 1
        if vertices is None or len(vertices) == 0 or ("boxes", ()) not in self.programs:
            return
        self.box_vbo = self.ctx.buffer(np.ascontiguousarray(vertices, np.float32).tobytes())
        self.box_vao = self.ctx.vertex_array(self.programs[("boxes", ())],
                                             [(self.box_vbo, "3f 4f", "in_position", "in_colour")])
        self.box_count = len(vertices)

    # --- drawing --------------------------------------------------------------------------
    def draw_view(self, settings, overlay, view=None) -> None:
        """Compose the view framebuffer: image, overlay and (if any) box outlines.

        overlay: None, or (lo, hi, log_scale, special_rgbs) for the channel in the data texture.
        Skipped when nothing it depends on changed since the last time.
        """
        if self.fbo is None or self.error is not None and ("image", ()) not in self.programs:
            return
        signature = (self.generation, self.size, settings, repr(overlay), view if self.box_count else None)
        if signature == self.composed:
            return
        tone = not (settings.exposure == 0.0 and settings.tone == "clamp" and settings.gamma == 1.0)
        defines = tuple(d for d, on in zip(IMAGE_SWITCHES, (tone, overlay is not None,
                                                            overlay is not None and overlay[2])) if on)
        prog = self.program("image", defines)
        if prog is None:
            return
        w, h = self.size
        self.fbo.use()
        self.ctx.viewport = (0, 0, w, h)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        self.colour.use(0)
        self.data.use(1)
        self.lut.use(2)
        for name, value in (("colour_tex", 0), ("data_tex", 1), ("lut_tex", 2),
                            ("exposure", float(settings.exposure)), ("gamma", float(settings.gamma)),
                            ("tone", TONE_CODE[settings.tone]), ("opacity", float(settings.opacity))):
            _set(prog, name, value)
        if overlay is not None:
            lo, hi, _, specials = overlay
            _set(prog, "lo", float(lo))
            _set(prog, "hi", float(hi))
            rgbs = np.zeros((MAX_SPECIALS, 3), np.float32)
            rgbs[:len(specials)] = np.asarray(specials, np.float32).reshape(-1, 3)[:MAX_SPECIALS]
            if "special_colour" in prog:
                prog["special_colour"].write(rgbs.tobytes())
        self._vao(prog).render(moderngl.TRIANGLES, vertices=3)
        if self.box_vao is not None and view is not None:
            self.ctx.enable(moderngl.BLEND)
            self.ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
            mvp = view_projection(view, w, h)
            _set(self.programs[("boxes", ())], "view_projection", tuple(mvp.T.astype(np.float32).ravel()))
            self.box_vao.render(moderngl.LINES, vertices=self.box_count)
            self.ctx.disable(moderngl.BLEND)
        self.composed = signature

    def blit(self, region, framebuffer_size) -> None:
        """Copy the view into region (x, y, w, h) of the window, y measured from the top."""
        prog = self.programs.get(("blit", ()))
        if self.fbo is None or prog is None:
            return
        x, y, w, h = region
        fb_w, fb_h = framebuffer_size
        self.ctx.screen.use()
        self.ctx.viewport = (int(x), int(fb_h - y - h), int(w), int(h))
        self.view_tex.use(0)
        _set(prog, "view_tex", 0)
        self._vao(prog).render(moderngl.TRIANGLES, vertices=3)
        self.ctx.viewport = (0, 0, fb_w, fb_h)

    def read_view(self) -> np.ndarray:
        """The composed view as (H, W, 3) uint8, row 0 at the top."""
        w, h = self.size
        raw = np.frombuffer(self.fbo.read(components=3, alignment=1), np.uint8).reshape(h, w, 3)
        return raw[::-1].copy()

    def read_window(self, framebuffer_size) -> np.ndarray:
        """The whole window (call before swap_buffers) as (H, W, 3) uint8, row 0 at the top."""
        fb_w, fb_h = framebuffer_size
        raw = self.ctx.screen.read(viewport=(0, 0, fb_w, fb_h), components=3, alignment=1)
        return np.frombuffer(raw, np.uint8).reshape(fb_h, fb_w, 3)[::-1].copy()
