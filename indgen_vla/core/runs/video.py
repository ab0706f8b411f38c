"""MP4 writing for episode videos (imageio-ffmpeg); the engine names files by axis, level, episode, outcome."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from indgen_vla.core.errors import ConfigError


def write_mp4(frames: Iterable[np.ndarray], path: str | Path, fps: int = 20) -> Path:
    """Encode uint8 HxWx3 frames (all the same size) as H.264 mp4 at ``fps``; returns the path written."""
    import imageio.v2 as imageio

    frames = list(frames)
    if not frames:
        raise ConfigError(f"no frames to write to {path}")
    if fps < 1:
        raise ConfigError(f"fps must be >= 1, got {fps}")
    shape = frames[0].shape
    for f in frames:
        if f.dtype != np.uint8 or f.ndim != 3 or f.shape[2] != 3 or f.shape != shape:
            raise ConfigError(f"video frames must all be uint8 {shape}; got {f.dtype} {f.shape}")
    h, w = shape[:2]
    pad = ((0, h % 2), (0, w % 2), (0, 0))  # H.264 needs even sides
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # encoded beside its name, then renamed: a kill mid-encode leaves no truncated video under a final name
    partial = path.with_name(f".{path.stem}.partial{path.suffix}")
    try:
        with imageio.get_writer(
            partial, fps=fps, codec="libx264", macro_block_size=2, quality=7, ffmpeg_log_level="error"
        ) as writer:
            for f in frames:
                writer.append_data(np.pad(f, pad, mode="edge") if any(p[1] for p in pad) else f)
        _check_complete(partial, len(frames))
        partial.replace(path)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return path


def _check_complete(path: Path, n_frames: int) -> None:
    """imageio's writer does not check ffmpeg's exit status, so a failed encode (a full disk) would pass as a
    video: count the frames back (one ffmpeg decode, ≈ 0.1 s for an episode's video)."""
    import imageio_ffmpeg

    try:
        written = imageio_ffmpeg.count_frames_and_secs(str(path))[0]
    except (RuntimeError, OSError) as error:
        raise OSError(
            f"video {path.name}: ffmpeg's output is unreadable ({str(error).splitlines()[0]}); disk full?"
        ) from error
    if written != n_frames:
        raise OSError(f"video {path.name}: ffmpeg wrote {written} of {n_frames} frames; disk full?")
