"""Frame ranges at production shape: every frame is one picklable task (render, write atomically,
return stats or the error) so the same code runs serially, in local worker processes
(`--workers N`), or on a Dask cluster (`--cluster ADDRESS`), with the same skip-and-resume rules.
A failing frame never stops the others."""

from __future__ import annotations

import glob
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from typing import Callable, Iterator

from ..core.errors import UserError


@dataclass(frozen=True)
class FrameTask:
    """Everything a worker needs to render and write one frame."""

    scene: str
    camera: str | None
    resolution: tuple[int, int] | None
    settings: dict
    frame: float
    output: str
    compression: str
    fingerprint: str


_renderers: dict = {}


def run_task(task: FrameTask) -> dict:
    """Render and write one frame (in whatever process runs it); never raises for a frame error."""
    from ..api import Renderer
    from ..output.files import output_fingerprint_write
    from ..core.settings import RenderSettings
    t0 = time.perf_counter()
    try:
        key = (task.scene, task.camera, task.resolution, tuple(sorted((k, repr(v)) for k, v in task.settings.items())))
        renderer = _renderers.get(key)
        if renderer is None:
            _renderers.clear()
            renderer = _renderers[key] = Renderer(task.scene, camera=task.camera, resolution=task.resolution,
                                                   settings=RenderSettings(**task.settings))
        result = renderer.render(task.frame)
        result.metadata["fingerprint"] = task.fingerprint
        output_fingerprint_write(task.output, result, task.compression, task.fingerprint)
        return {"frame": task.frame, "output": task.output, "stats": result.stats,
                "seconds": time.perf_counter() - t0}
    except UserError as exc:
        return {"frame": task.frame, "output": task.output, "error": str(exc), "user_error": True}
    except (OSError, MemoryError) as exc:   # a full disk, a folder gone, too little memory: named, not raw
        return {"frame": task.frame, "output": task.output, "user_error": True,
                "error": f"cannot render or write {task.output}: {getattr(exc, 'strerror', None) or exc}"}
    except Exception as exc:  # a crash in one frame is reported, the others go on
        return {"frame": task.frame, "output": task.output, "error": f"{type(exc).__name__}: {exc}"}


def remove_stale_temporaries(outputs: list[str]) -> int:
    """Delete temporaries a killed run left beside the outputs: only files of our own naming
    (output.temporary_prefix) whose owner is a process of this host that no longer runs."""
    import socket

    from ..output.files import TEMP_PREFIX
    host = socket.gethostname().replace("-", "_")
    removed = 0
    for folder in {os.path.dirname(os.path.abspath(p)) for p in outputs}:
        for path in glob.glob(os.path.join(folder, TEMP_PREFIX + "*")):
            parts = os.path.basename(path)[len(TEMP_PREFIX):].split("-")
            if len(parts) < 3 or parts[0] != host or not parts[1].isdigit() or _alive(int(parts[1])):
                continue
            try:
                os.unlink(path)
                removed += 1
            except OSError:
                pass
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:   # another user's live process
        return True
    return True


def execute(tasks: list[FrameTask], workers: int = 1, cluster: str | None = None,
            fail_fast: bool = False) -> Iterator[dict]:
    """Run tasks serially, in `workers` processes, or on a Dask cluster; yield results as they end."""
    if not tasks:
        return
    if cluster:
        try:
            from distributed import Client
        except ImportError:
            raise UserError("--cluster needs Dask: pip install 'warp_blur[farm]'") from None
        try:
            client = Client(cluster, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise UserError(f"cannot reach the cluster at {cluster}: {exc}") from None
        try:
            futures = client.map(run_task, tasks, pure=False)
            from distributed import as_completed as dask_completed
            for fut in dask_completed(futures):
                res = fut.result()
                yield res
                if fail_fast and "error" in res:
                    client.cancel(futures)
                    return
        except BaseException:
            client.cancel(futures)
            raise
        finally:
            client.close()
        return
    if workers > 1:
        import multiprocessing
        threads = max(1, (os.cpu_count() or 1) // workers)
        tasks = [FrameTask(**{**asdict(t), "settings": {**t.settings, "threads": t.settings.get("threads") or threads}})
                 for t in tasks]
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
        try:
            futures = [pool.submit(run_task, t) for t in tasks]
            for fut in as_completed(futures):
                res = fut.result()
                yield res
                if fail_fast and "error" in res:
                    break
        except BaseException:   # Ctrl-C (or the caller stopping): no worker goes on rendering
            _stop_workers(pool)
            raise
        _stop_workers(pool)
        return
    for t in tasks:
        res = run_task(t)
        yield res
        if fail_fast and "error" in res:
            return


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started and end the worker processes now (their temporaries are then
    stale: a dead owner's, removed by remove_stale_temporaries)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        if proc.is_alive():
            proc.terminate()
    for proc in processes:
        proc.join(timeout=5)


def render_frames(scene: str, frames: list[float], *, settings=None, camera: str | None = None,
                  resolution: tuple[int, int] | None = None,
                  progress: Callable[[int, int, float], None] | None = None) -> Iterator[tuple[float, object]]:
    """Python API for pipelines: yield (frame, RenderResult) for each frame, in order, from one
    opened stage; progress(done, total, frame) is called after each frame."""
    from ..api import Renderer
    renderer = Renderer(scene, camera=camera, resolution=resolution, settings=settings)
    for i, frame in enumerate(frames):
        result = renderer.render(float(frame))
        if progress:
            progress(i + 1, len(frames), float(frame))
        yield float(frame), result
