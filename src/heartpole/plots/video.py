"""Videos of episodes: the env's ``rgb_array`` frames written as MP4 or GIF."""

from __future__ import annotations

import errno
import os
import re
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from heartpole.plots.canvas import VIDEO_SUFFIXES
from heartpole.plots.episode import act, make_env
from heartpole.policies import Policy
from heartpole.render import BASE_HEIGHT, WIDTH

if TYPE_CHECKING:
    from heartpole.env import HeartPole

GIF_FRAME_BYTES = WIDTH * BASE_HEIGHT
"""The least memory a GIF's frame takes until the GIF is written: Pillow keeps every frame, as one byte a pixel,
until it has seen the last (a variant's extra gauges make frames taller)."""


def episode_frames(
    policy: Policy, env_id: str = "HeartPole-v0", seed: int = 0, **env_kwargs: Any
) -> Iterator[np.ndarray]:
    """The ``rgb_array`` frames of one episode: the first state after reset, then one frame per step."""
    env = make_env(env_id, render_mode="rgb_array", **env_kwargs)
    try:
        observation, _ = env.reset(seed=seed)
        yield cast(np.ndarray, env.render())  # render_mode="rgb_array"
        done, steps = False, 0
        while not done:
            left = int(cast("HeartPole", env.unwrapped).max_steps) - steps
            observation, _, terminated, truncated, _ = env.step(act(policy, observation, left))
            steps += 1
            yield cast(np.ndarray, env.render())
            done = terminated or truncated
    finally:
        env.close()


def write_video(frames: Iterable[np.ndarray], path: str | Path, fps: float = 8.0) -> int:
    """Write RGB frames to ``path`` (``.mp4`` through imageio-ffmpeg, ``.gif`` through Pillow); return the count.

    Frames are streamed: an MP4 of a long episode never holds all its frames in memory. An MP4 is read back
    ([`check_mp4`][heartpole.plots.video.check_mp4]): a video ffmpeg failed to finish raises ``OSError``.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise ValueError(f"unsupported video type {suffix or '(none)'!r}; use one of {list(VIDEO_SUFFIXES)}")
    return _write_mp4(frames, path, fps) if suffix == ".mp4" else _write_gif(frames, path, fps)


def _write_mp4(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> int:
    try:
        import imageio.v2 as imageio
    except ImportError as error:
        raise ImportError('MP4 videos need imageio and imageio-ffmpeg: pip install "heartpole[plot]"') from error
    count = 0
    options: dict[str, Any] = {"codec": "libx264", "quality": 7, "macro_block_size": 2, "ffmpeg_log_level": "quiet"}
    try:
        with imageio.get_writer(path, format="FFMPEG", fps=fps, **options) as writer:
            for frame in frames:
                writer.append_data(frame)  # type: ignore[attr-defined]  # typed as v3's base; v2's writers have it
                count += 1
    except OSError as error:  # ffmpeg stopped taking frames ("Broken pipe"): a full disk, or ffmpeg failed
        first = next((line.strip() for line in str(error).splitlines() if line.strip()), type(error).__name__)
        raise _unfinished(path, f"ffmpeg stopped after {count} frames: {first}") from None
    check_mp4(path, count)
    return count


def _unfinished(path: str | Path, said: str) -> OSError:
    """The error of a video ffmpeg did not finish: ``ENOSPC`` when its disk is full, else ``EIO``; ``said`` is
    what went wrong, in words."""
    if shutil.disk_usage(Path(path).parent).free == 0:
        return OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)} (the video is incomplete: {said})", str(path))
    return OSError(errno.EIO, f"ffmpeg did not write a whole video ({said})", str(path))


def check_mp4(path: str | Path, count: int) -> None:
    """Check that ffmpeg wrote a whole MP4 of ``count`` frames at ``path``: its container reads back and holds
    them all (read without decoding, so it takes a moment).

    imageio does not look at ffmpeg's exit status: a full disk (``Error writing trailer: No space left on
    device``) left a file no player can open, reported as written.

    Raises:
        OSError: naming ``path``: ``ENOSPC`` when its disk is full, else ``EIO``, with ffmpeg's last words.
    """
    import subprocess

    import imageio_ffmpeg

    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-hide_banner", "-i", str(path)]
    command += ["-map", "0:v:0", "-c", "copy", "-f", "null", "-"]
    run = subprocess.run(command, capture_output=True, text=True, errors="replace", check=False)
    found = re.findall(r"frame=\s*(\d+)", run.stderr)
    if run.returncode == 0 and found and int(found[-1]) == count:
        return
    last = next((line.strip() for line in reversed(run.stderr.splitlines()) if line.strip()), "no output")
    said = f"{int(found[-1])} of {count} frames readable" if run.returncode == 0 and found else f"ffmpeg: {last}"
    raise _unfinished(path, said)


def _write_gif(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> int:
    try:
        from PIL import Image
    except ImportError as error:
        raise ImportError('GIF videos need Pillow: pip install "heartpole[plot]"') from error
    images = (Image.fromarray(frame) for frame in frames)
    first = next(images)
    count = [1]

    def counted() -> Iterator[Any]:
        for image in images:
            count[0] += 1
            yield image

    first.save(path, format="GIF", save_all=True, append_images=counted(), duration=round(1000 / fps), loop=0)
    return count[0]
