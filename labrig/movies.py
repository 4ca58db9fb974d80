"""MP4 movies drawn frame by frame with matplotlib, written atomically and playable everywhere.

Movies are H.264 in ``yuv420p`` with even frame sizes and the ``moov`` index at the start of the file
(``+faststart``): the combination that browsers, slide decks and phones play, and that starts playing
before the whole file has arrived.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .files import StreamedFile
from .validate import InputError, count, real

#: Pixel format of every movie (4:2:0 chroma: what players expect of H.264).
PIXEL_FORMAT = "yuv420p"
#: Largest frame rate, frames/s.
MAX_FPS = 240.0
#: Largest frame side, pixels.
MAX_SIZE_PX = 4096


class FigureMovie(StreamedFile):
    """An MP4 built frame by frame from one reused matplotlib figure (written atomically).

    Subclasses draw on `figure` and call `add_frame`. Frames go straight to ffmpeg (H.264,
    yuv420p, ``+faststart``), so memory does not grow with the number of frames; the movie is
    streamed to a temporary file beside ``path`` and renamed onto it by `close`; if an exception
    leaves the ``with`` block the temporary file is removed and ``path`` is left untouched.

    Parameters
    ----------
    path : str or Path
        Output file (``.mp4``).
    fps : float
        Frames per second, in (0, `MAX_FPS`].
    size_px : int
        Width and height of a frame, pixels: even (H.264 in yuv420p needs even sizes), in
        [16, `MAX_SIZE_PX`].
    """

    def __init__(self, path, fps: float, size_px: int):
        fps = real("fps", fps, 0.0, MAX_FPS, low_open=True)
        size_px = count("size_px", size_px, 16, MAX_SIZE_PX)
        if size_px % 2:
            raise InputError(f"size_px must be even (H.264 in yuv420p needs even sizes), got {size_px}")
        import imageio.v2 as imageio

        self.fps = fps
        self.size_px = int(size_px)
        self.frames = 0
        super().__init__(path)
        try:
            self._writer = imageio.get_writer(self._tmp, format="FFMPEG", fps=fps, codec="libx264",
                                              pixelformat=PIXEL_FORMAT, macro_block_size=1,
                                              output_params=["-movflags", "+faststart"])
        except BaseException:
            self._tmp.unlink(missing_ok=True)
            raise
        dpi = 100
        self.figure = Figure(figsize=(self.size_px / dpi, self.size_px / dpi), dpi=dpi)
        self._canvas = FigureCanvasAgg(self.figure)

    def add_frame(self) -> None:
        """Render `figure` and append it as one frame."""
        if self.closed:
            raise ValueError(f"{type(self).__name__} for {self.path} is closed")
        self._canvas.draw()
        frame = np.asarray(self._canvas.buffer_rgba())[:, :, :3]
        if frame.shape[:2] != (self.size_px, self.size_px):  # would make ffmpeg fail obscurely
            raise RuntimeError(f"rendered frame is {frame.shape[:2]}, expected {self.size_px} px square")
        self._writer.append_data(np.ascontiguousarray(frame))
        self.frames += 1

    def _close_stream(self) -> None:
        self._writer.close()

    def _is_empty(self) -> bool:
        return self.frames == 0
