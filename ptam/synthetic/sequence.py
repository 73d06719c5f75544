"""Rendered sequences on disk (TUM RGB-D layout) and their cache.

Layout of a sequence directory::

    rgb/000000.png ...   frames (8-bit grey)
    rgb.txt              "timestamp rgb/NNNNNN.png" per frame (TUM RGB-D)
    groundtruth.txt      camera-to-world poses, TUM format "t tx ty tz qx qy qz qw"
    camera.yaml          the camera model (ptam.camera.save_camera)
    scene.yaml           the resolved scene description (renders the same sequence again)
    video.avi            optional: the frames as lossless FFV1

``ensure_sequence`` renders a scene once into the cache directory (``PTAM_CACHE_DIR`` if set, else the
``synthetic.cache_dir`` config value), in a directory named by the scene and the hash of its resolved
description. It renders into a temporary directory and renames it into place, so an interrupted render
never leaves a broken entry, and a later call finds the finished one and returns at once.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import tempfile
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np
import yaml
from tqdm import tqdm

from ..camera import save_camera
from ..config import SyntheticConfig
from ..errors import InputError, PtamError
from ..eval.tum_io import write_tum
from .scene import Scene, load_scene

CACHE_ENV = "PTAM_CACHE_DIR"
VIDEO_FILE = "video.avi"
_VIDEO_FOURCC = "FFV1"
_DIR_MODE = 0o755
_FILE_MODE = 0o644


def frame_name(i: int) -> str:
    return f"rgb/{i:06d}.png"


def write_video(path: Path, frames, fps: float, size: tuple[int, int]) -> None:
    """Grey frames to a lossless FFV1 AVI."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*_VIDEO_FOURCC), fps, size, isColor=False)
    if not writer.isOpened():
        raise PtamError(f"OpenCV cannot write an {_VIDEO_FOURCC} video to {path}")
    try:
        for f in frames:
            writer.write(f)
    finally:
        writer.release()


def write_sequence(
    scene: Scene, out: str | os.PathLike, video: bool = False, threads: int = 2, progress: bool = True
) -> Path:
    """Render every frame of ``scene`` into ``out`` (created; must not hold a sequence already)."""
    out = Path(out)
    (out / "rgb").mkdir(parents=True, exist_ok=True)
    scene.prepare()  # build the textures once, before the worker threads share them

    def work(i: int) -> np.ndarray:
        img = scene.render_frame(i)
        if not cv2.imwrite(str(out / frame_name(i)), img):
            raise PtamError(f"cannot write {out / frame_name(i)}")
        return img

    def rendered():
        for f in pool.map(work, range(scene.n_frames)):
            bar.update(1)
            yield f

    cam = scene.camera
    bar = tqdm(total=scene.n_frames, desc=f"rendering {scene.name}", unit="frame", disable=None if progress else True)
    pool = ThreadPoolExecutor(max_workers=max(1, threads))
    try:
        if video:
            write_video(out / VIDEO_FILE, rendered(), scene.fps, (cam.width, cam.height))
        else:
            for _ in rendered():
                pass
    finally:
        pool.shutdown(wait=True, cancel_futures=True)  # Ctrl-C must not wait for the remaining frames
        bar.close()
    with open(out / "rgb.txt", "w") as f:
        f.write(f"# grey images of synthetic scene '{scene.name}'\n# timestamp filename\n")
        f.writelines(f"{t:.9f} {frame_name(i)}\n" for i, t in enumerate(scene.timestamps))
    write_tum(
        out / "groundtruth.txt",
        scene.timestamps,
        scene.poses_T_wc,
        header=f"ground truth of synthetic scene '{scene.name}'",
    )
    save_camera(cam, out / "camera.yaml")
    with open(out / "scene.yaml", "w") as f:
        f.write(f"# scene '{scene.name}' (hash {scene.hash}), resolved\n")
        yaml.safe_dump(scene.spec, f, sort_keys=False, default_flow_style=None, width=120)
    return out


def cache_root(cache_dir: str | os.PathLike) -> Path:
    """``PTAM_CACHE_DIR`` if set, else ``cache_dir`` (the configured ``synthetic.cache_dir``)."""
    if os.environ.get(CACHE_ENV):
        cache_dir = os.environ[CACHE_ENV]
    return Path(os.path.expanduser(os.fspath(cache_dir)))


def ensure_sequence(name_or_path: str | os.PathLike, cfg: SyntheticConfig, video: bool = False) -> Path:
    """The cached rendering of a scene (bundled name or file), rendered now if missing, under ``cfg.cache_dir``
    with ``cfg.render_threads`` threads; returns its directory."""
    scene = load_scene(name_or_path)
    root = cache_root(cfg.cache_dir) / "synthetic"
    final = root / f"{scene.name}-{scene.hash}"
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot create the cache directory {root}: {e.strerror}") from None
    if not final.is_dir():
        with _rendering(root / f".{final.name}.lock"):
            if not final.is_dir():  # else another process rendered it while this one waited
                _render_into(scene, root, final, video, cfg.render_threads)
    if video and not (final / VIDEO_FILE).is_file():
        fd, tmp_video = tempfile.mkstemp(prefix=".video.", suffix=".avi", dir=final)
        os.close(fd)
        try:
            frames = (cv2.imread(str(final / frame_name(i)), cv2.IMREAD_GRAYSCALE) for i in range(scene.n_frames))
            write_video(Path(tmp_video), frames, scene.fps, (scene.camera.width, scene.camera.height))
            os.chmod(tmp_video, _FILE_MODE)
            os.replace(tmp_video, final / VIDEO_FILE)
        finally:
            if os.path.exists(tmp_video):
                os.unlink(tmp_video)
    return final


@contextlib.contextmanager
def _rendering(lock_path: Path) -> Iterator[None]:
    """Held while a scene is rendered into the cache: a second process that wants the same scene (two runs, or the
    test suite's two workers) waits for the first render instead of repeating it (desk_blur: 65 s on two cores).
    The lock is the kernel's (flock), so a killed render leaves no stale lock behind; its file is removed with the
    lock held, which is safe because whoever takes a lock next looks for the rendered entry before rendering.
    Where the file system cannot lock (some network mounts) the render goes ahead unlocked: the atomic rename keeps
    the cache whole, and two processes may then both render."""
    fd = _lock(lock_path)
    try:
        yield
    finally:
        if fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(lock_path)
            os.close(fd)  # releases the lock


def _lock(path: Path) -> int | None:
    """A descriptor of ``path`` locked exclusively (waiting for another holder), or None where it cannot be locked."""
    fd = None
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT, _FILE_MODE)
        fcntl.flock(fd, fcntl.LOCK_EX)
        return fd
    except OSError:
        if fd is not None:
            os.close(fd)
        return None


def _render_into(scene: Scene, root: Path, final: Path, video: bool, threads: int) -> None:
    """Render ``scene`` into a private directory under ``root``, then rename it to ``final`` (atomic: a reader sees
    the whole sequence or none)."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", dir=root))
    try:
        os.chmod(tmp, _DIR_MODE)  # mkdtemp makes it private; the finished entry is shared like any directory
        write_sequence(scene, tmp, video=video, threads=threads)
        try:
            os.rename(tmp, final)
        except OSError:
            if not final.is_dir():  # not a concurrent render that finished first
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def copy_sequence(src: Path, out: str | os.PathLike, video: bool) -> Path:
    """Copy a rendered sequence into ``out`` (which must be missing or empty)."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(f"output directory {out} exists and is not empty")
    skip = (".*",) if video else (".*", VIDEO_FILE)
    try:
        shutil.copytree(src, out, ignore=shutil.ignore_patterns(*skip), dirs_exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot write {out}: {e}") from None
    return out
