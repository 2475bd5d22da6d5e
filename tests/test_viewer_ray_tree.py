"""The inspector's ray tree in the viewer: the rays drawn over the image (no display needed), and
under Xvfb a click on a pixel in the penumbra lists its rays, a chosen ray's subdivision trace
replaces the pixel's in the plot, table and outlines, and everything is drawn without errors."""
from __future__ import annotations

import json

import numpy as np
import pytest

from tracer.camera import view_of
from tracer.geometry import prepare
from tracer.options import Options
from tracer.ray_tree import ray_tree, trace_steps
from tracer.render import render
from tracer.stats import json_safe
from tracer.trace_one import trace_pixel
from viewer_util import SIZE, TEAPOT, run_view, teapot, warm_kernels, xvfb  # noqa: F401


@pytest.fixture(scope="module")
def penumbra_pixel(teapot):
    """A floor pixel of the window tests' image in the penumbra: lit and occluded shadow rays."""
    frame = render(teapot, Options(), size=SIZE)
    ys, xs = np.nonzero((frame.penumbra == 1) & (frame.shadow > 0.1) & (frame.shadow < 0.9) & (frame.patch == 32))
    assert len(xs), "the teapot's shadow has a penumbra on the floor"
    return int(xs[len(xs) // 2]), int(ys[len(ys) // 2])


def traced_tree(scene, pixel):
    geom = prepare(scene, "f32")
    tree = ray_tree(scene, Options(), *pixel, size=SIZE, geometry=geom)
    trace_steps(tree, scene, geom, Options(), view_of(scene), SIZE)
    return tree


def test_rays_are_drawn_from_their_origins_the_chosen_one_white_and_last(teapot, penumbra_pixel):
    from viewer.ray_lines import CHOSEN_RGBA, RAY_RGBA, ray_tree_vertices
    tree = traced_tree(teapot, penumbra_pixel)
    view = view_of(teapot)
    rays = tree.rays
    verts = ray_tree_vertices(tree, view)
    assert verts.shape[1] == 7 and verts.dtype == np.float32
    boxes = sum(r.hit and r.box_min is not None for r in rays[1:])
    assert len(verts) == 2 * (len(rays) - 1) + (24 + 6) * boxes  # a segment each; a box and a cross per hit
    first = rays[1]
    assert np.allclose(verts[0, :3], first.origin, rtol=1e-6)
    lit = [r for r in rays if r.kind == "shadow" and not r.hit]
    occluded = [r for r in rays if r.kind == "shadow" and r.hit]
    assert lit and occluded and all(r.box_min is not None for r in occluded)  # traced: the occluder's box
    for kind in ("lit", "occluded"):
        assert np.any(np.all(np.isclose(verts[:, 3:], RAY_RGBA[kind]), axis=1)), kind
    chosen = rays.index(occluded[0])
    last = ray_tree_vertices(tree, view, chosen)
    tail = 2 + 24 + 6  # the chosen ray's segment, its hit box and cross, drawn last (on top)
    assert len(last) == len(verts) and np.allclose(last[-tail:, 3:], CHOSEN_RGBA)
    assert np.allclose(last[-tail, :3], occluded[0].origin, rtol=1e-6)


def test_click_lists_the_ray_tree_and_draws_the_chosen_ray(xvfb, warm_kernels, tmp_path, teapot, penumbra_pixel):
    from viewer.picking import outline_vertices
    from viewer.ray_lines import ray_tree_vertices
    from viewer.state import Inspection
    x, y = penumbra_pixel
    want = traced_tree(teapot, penumbra_pixel)  # first: its kernels reach the disk cache the viewer loads
    dump = tmp_path / "trace.json"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--click", f"{x},{y}", "--dump-inspector", dump],
                                 tmp_path, hooks="choose-ray")
    assert code == 0, err
    assert not [m for m in status["messages"] if m["level"] == "error"], status["messages"]
    got = status["inspector"]["ray_tree"]
    assert got["error"] is None and got["rays"] == len(want.rays) > 2 and got["rows_drawn"] >= 3
    k = got["chosen"]
    assert want.rays[k].kind == "shadow" and got["shown_boxes"] == len(want.rays[k].steps.steps_f) > 0
    ins = Inspection((x, y), trace_pixel(teapot, Options(), x, y, size=SIZE), step=-1, view=view_of(teapot),
                     tree=want, ray=k)
    drawn = len(outline_vertices(ins)) + len(ray_tree_vertices(want, view_of(teapot), k))
    assert status["inspector"]["outline_vertices"] == drawn  # the chosen ray's boxes and every ray
    tree = json.loads(dump.read_text())["ray_tree"]
    assert tree == json_safe(want.to_json())  # the dump's new key: the tracer's ray tree


def test_a_failing_ray_tree_is_logged_and_the_pixel_s_trace_kept(teapot, monkeypatch):
    from types import SimpleNamespace

    from viewer import interaction
    from viewer.state import AppState
    from viewer.worker import GeometryCache

    def broken(*args):
        raise RuntimeError("no tree today")

    monkeypatch.setattr(interaction, "inspect_tree", broken)
    state = AppState(scene=teapot, view=view_of(teapot), image_size=SIZE)
    boxes = []
    viewer = SimpleNamespace(state=state, geometry=GeometryCache(), display=SimpleNamespace(set_boxes=boxes.append))
    ui = interaction.Interaction(viewer)
    job = ui.inspect(64, 72)
    assert job.tree_done.wait(300)
    ui.refresh_inspection()
    ins = state.inspector
    assert ins is not None and ins.trace.hit and ins.tree is None and "no tree today" in ins.tree_error
    assert ui.tree_pending is None and state.inspecting is None
    assert any(level == "error" and "no tree today" in text for _, level, text in state.messages)
    assert len(boxes[-1]) > 0  # the pixel's boxes are drawn all the same
