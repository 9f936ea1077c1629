"""Warnings (core/log.py): said once per prim within a Renderer's scope, reported in that
Renderer's stats only, and carried to the threads a frame hands work to."""

from __future__ import annotations

import threading

from authoring import add_camera, add_quad, add_textured_material, bind, new_stage, set_st

import warp_blur as wb
from warp_blur.core import log, parallel

RES = (32, 24)


def stage_with_a_volume(path: str, volume: str = "/World/Thing") -> str:
    """A camera, a quad and a prim of a type warp_blur does not render (a Volume) at `volume`."""
    stage = new_stage(path)
    add_camera(stage)
    add_quad(stage, "/World/Quad", 1.0, 1.0)
    stage.DefinePrim(volume, "Volume")
    stage.GetRootLayer().Save()
    return path


def said_about(result, prim: str) -> list[str]:
    return [w for w in result.stats["warnings"] if prim in w]


def test_two_stages_each_report_their_prim_though_it_has_the_same_path(scene_path):
    """A pipeline process renders one stage, then another with a prim of the same path that it
    cannot render either: both results say so (the first version said a prim path once per
    process, and the second stage's stats had nothing)."""
    first = wb.render(stage_with_a_volume(scene_path()), frame=1, resolution=RES, method="analytic")
    second = wb.render(stage_with_a_volume(scene_path()), frame=1, resolution=RES, method="analytic")
    assert len(said_about(first, "/World/Thing")) == 1, first.stats["warnings"]
    assert len(said_about(second, "/World/Thing")) == 1, second.stats["warnings"]


def test_a_renderer_says_a_warning_once_over_its_frames(scene_path):
    renderer = wb.Renderer(stage_with_a_volume(scene_path()), resolution=RES,
                           settings=wb.RenderSettings(method="analytic"))
    assert said_about(renderer.render(1), "/World/Thing")
    assert not said_about(renderer.render(2), "/World/Thing")


def test_renderers_in_two_threads_report_only_their_own_warnings(scene_path):
    """Two Renderers rendering at once, each in its thread: each frame's stats name its own
    stage's prim and never the other's (one process-wide list let either take both)."""
    names = ["/World/OnlyA", "/World/OnlyB"]
    results: dict[str, list] = {name: [] for name in names}

    def render_all(name: str) -> None:
        for _ in range(3):   # a new Renderer each time: each first frame says its prim again
            results[name].append(wb.render(stage_with_a_volume(scene_path(), name), frame=1, resolution=RES,
                                           method="stochastic", samples=4))
    threads = [threading.Thread(target=render_all, args=(name,)) for name in names]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for name, other in (names, names[::-1]):
        assert len(results[name]) == 3
        for result in results[name]:
            assert len(said_about(result, name)) == 1, result.stats["warnings"]
            assert not said_about(result, other), result.stats["warnings"]


def test_each_renderer_hears_of_an_unreadable_texture_the_process_read_once(scene_path, tmp_path):
    """Images are read once per process (usd/textures.py keeps them, and keeps a failure as
    None): a second Renderer of a stage whose texture cannot be read still reports it (the cache
    used to answer without a word, so only the first Renderer's stats said it)."""
    (tmp_path / "broken.png").write_bytes(b"not an image at all")
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    quad = add_quad(stage, "/World/Quad", 1.0, 1.0)
    set_st(quad, [(0, 0), (1, 0), (1, 1), (0, 1)])
    bind(quad.GetPrim(), add_textured_material(stage, "/World/Looks/Broken", "broken.png"))
    stage.GetRootLayer().Save()
    for _ in range(2):
        result = wb.render(path, frame=1, resolution=RES, method="analytic")
        assert len(said_about(result, "broken.png")) == 1, result.stats["warnings"]


def test_work_carried_to_other_threads_warns_into_the_callers_scope():
    """A frame's helper thread (parallel.Background) and its jobs (map_threads) say their
    warnings into the scope of the frame that started them; a bare thread says them into the
    process's scope."""
    mine = log.WarningScope()
    with log.scope(mine):
        parallel.Background(lambda: log.warn_once("bg", "from a helper"), "test_log").result()
        parallel.map_threads(lambda i: log.warn_once(f"job{i}", f"from job {i}"), [0, 1, 2], threads=2)
        bare = threading.Thread(target=lambda: log.warn_once("bare", "from a bare thread"))
        bare.start()
        bare.join()
    assert sorted(mine.take()) == ["from a helper", "from job 0", "from job 1", "from job 2"]
    assert "from a bare thread" in log.take_warnings()   # outside every scope: the process's
    log.reset()


def test_a_key_is_said_once_per_scope_and_scopes_nest():
    log.reset()
    outer = log.WarningScope()
    inner = log.WarningScope()
    with log.scope(outer):
        log.warn_once("k", "outer says")
        log.warn_once("k", "outer says again")
        with log.scope(inner):
            log.warn_once("k", "inner says")
        log.warn_once("k2", "outer again")
    assert outer.take() == ["outer says", "outer again"]
    assert inner.take() == ["inner says"]
    assert log.take_warnings() == []    # the process's scope heard none of it
    assert outer.take() == []           # taken once
