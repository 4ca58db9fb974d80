"""What a player sees in an MP4: codec, pixel format, size, frame rate, frame count, index position."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import imageio_ffmpeg


def top_level_boxes(path: Path) -> list[str]:
    """The names of the MP4's top-level boxes (atoms), in file order."""
    names, data = [], Path(path).read_bytes()
    at = 0
    while at + 8 <= len(data):
        size = int.from_bytes(data[at:at + 4], "big")
        names.append(data[at + 4:at + 8].decode("latin-1"))
        if size == 1:  # 64-bit size follows
            size = int.from_bytes(data[at + 8:at + 16], "big")
        if size < 8:
            break
        at += size
    return names


def probe(path: Path) -> dict:
    """Codec, pixel format, width, height, fps (as ffmpeg reads the file), frame count and box order."""
    ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
    info = subprocess.run([ffmpeg, "-hide_banner", "-i", str(path)], capture_output=True, text=True, timeout=120).stderr
    video = next(line for line in info.splitlines() if "Video:" in line)
    codec = re.search(r"Video: (\w+)", video).group(1)
    pix_fmt = re.search(r"Video: \w+[^,]*, (\w+)", video).group(1)
    width, height = map(int, re.search(r", (\d+)x(\d+)", video).groups())
    fps = float(re.search(r", ([\d.]+) fps", video).group(1))
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    return {"codec": codec, "pix_fmt": pix_fmt, "width": width, "height": height, "fps": fps, "frames": frames,
            "boxes": top_level_boxes(path)}


def assert_playable(path: Path, frames: int, fps: float, size_px: int) -> None:
    """H.264 in yuv420p, even square frames of ``size_px``, ``frames`` frames at ``fps``, index first."""
    found = probe(path)
    assert found["codec"] == "h264" and found["pix_fmt"] == "yuv420p", found
    assert found["width"] == found["height"] == size_px and size_px % 2 == 0, found
    assert found["frames"] == frames and abs(found["fps"] - fps) < 1e-6, found
    boxes = found["boxes"]
    assert "moov" in boxes and "mdat" in boxes and boxes.index("moov") < boxes.index("mdat"), boxes  # +faststart


def read_frames(path: Path) -> list:
    """Every frame of the movie, decoded by ffmpeg: RGB arrays of shape (height, width, 3).

    Read with one ``subprocess.run`` (its pipes closed when it returns): imageio's ffmpeg reader leaves the
    pipes of its ffmpeg process open (a ResourceWarning, an error in this suite).
    """
    import numpy as np

    found = probe(path)
    raw = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path), "-f", "rawvideo",
                          "-pix_fmt", "rgb24", "-"], capture_output=True, timeout=120, check=True).stdout
    shape = (found["height"], found["width"], 3)
    frames = np.frombuffer(raw, dtype=np.uint8).reshape((-1, *shape))
    return list(frames)
