"""The thesis's design tool in Jupyter: a board that runs live in a notebook widget.

In a notebook, the last line shows the widget (here it is not run: it needs a notebook's kernel):

>>> from qdots.interactive import LiveBoard
>>> board = LiveBoard(seed=1)          # doctest: +SKIP
>>> board                              # doctest: +SKIP

`LiveBoard` is a thin layer of ipywidgets controls over `qdots.interactive.live.LiveRun`,
which does everything through the public `Scene` / `Simulation` / forces
API. The canvas is an ipympl figure (matplotlib's Agg renderer in the kernel,
streamed to the notebook), updated every ``frame_steps`` time steps.

Not blocking the kernel: *start* creates an asyncio task on the kernel's own
event loop (ipykernel runs one; cells and widget messages are served by it).
The task advances one frame, redraws, then awaits ``asyncio.sleep``, which
hands the loop back so that button clicks, slider moves and new cells are
handled between frames. A frame is synchronous, so keep ``frame_steps`` small
enough that one frame takes well under a second. Outside a running event loop
(a script), call `LiveBoard.step` or use `qdots.interactive.live.LiveRun` directly.

Needs the ``widgets`` extra: ``pip install "nanodisorder[widgets]"`` (ipywidgets, ipympl).
"""

from __future__ import annotations

import asyncio
import html

from labrig.validate import real
from labrig.widgets import require_widgets, widget_figure

from ..engine import ENGINES
from ..presets import GRATING_WIDTH
from ..render import BoardArtists
from .live import GRAVITY_MODES, LiveRun

#: Largest canvas, inches a side: 2,000 px at matplotlib's 100 dpi, wider than a notebook's page (every
#: frame redraws all of it).
MAX_SIZE = 20.0
#: Longest pause after a frame, s: beyond it the board looks stopped.
MAX_FRAME_PAUSE = 60.0


def _error(text: str) -> str:
    return f"<span style='color:#b00'>{html.escape(text)}</span>"


def _html_table(rows: list[tuple[str, str]]) -> str:
    cells = "".join(f"<tr><td>{key}</td><td style='text-align:right'><b>{value}</b></td></tr>" for key, value in rows)
    return f"<table>{cells}</table>"


class LiveBoard:
    """A notebook widget that runs a `qdots.interactive.live.LiveRun` live.

    Parameters
    ----------
    live : qdots.interactive.live.LiveRun, optional
        The board to run; default ``LiveRun(**kwargs)``.
    frame_pause : float
        Wall-clock pause after each frame, s (in [0, `MAX_FRAME_PAUSE`]): time left to the kernel
        for clicks and cells.
    size : float
        Width and height of the canvas, inches (in (0, `MAX_SIZE`]; 4.8: 480 px, room for the controls
        beside it in a notebook next to JupyterLab's file browser; on a narrower page the controls go below).
    **kwargs
        Passed to `qdots.interactive.live.LiveRun` when ``live`` is not given (``scene``,
        ``knobs``, ``seed``, ``frame_steps``, engine settings).

    Attributes
    ----------
    controls : dict of ipywidgets value widgets
        ``dt``, ``elasticity``, ``vdw_r0``, ``thermal``, ``drag``, ``gravity``,
        ``gravity_magnitude`` (the `qdots.interactive.live.Knobs`), ``frame_steps``, the wall
        ends ``wall_x0`` ... ``wall_y1``, the grating ``pitch``, the drop
        parameters ``n_dots``, ``mean_diameter``, ``sigma``, ``interval``, and the
        file names ``state_path``, ``movie_path``.
    buttons : dict of ipywidgets buttons
        ``start``, ``pause``, ``step``, ``add_wall``, ``add_grating``,
        ``clear_walls``, ``drop``, ``save`` and ``record`` (starts a movie, or finishes it).
    readout, status : ipywidgets.HTML
        The live measures, and the last message or error.
    figure : matplotlib.figure.Figure
        The canvas figure (its ``canvas`` is the ipympl widget).
    ui : ipywidgets.Box
        The whole widget (what displaying the LiveBoard shows).
    """

    def __init__(self, live: LiveRun | None = None, *, frame_pause: float = 0.02, size: float = 4.8, **kwargs):
        self.frame_pause = real("frame_pause", frame_pause, 0.0, MAX_FRAME_PAUSE, unit="s")
        size = real("size", size, 0.0, MAX_SIZE, low_open=True, unit="in")
        w = require_widgets("qdots.interactive")
        self.live = LiveRun(**kwargs) if live is None else live
        if not isinstance(self.live, LiveRun):
            raise TypeError(f"live must be a qdots.interactive.live.LiveRun, got {type(self.live).__name__}")
        self._task: asyncio.Task | None = None
        self._restoring = False
        knobs, (width, height) = self.live.knobs, self.live.sim.scene.box
        text = {"style": {"description_width": "initial"}, "layout": w.Layout(width="145px")}
        slider = {"continuous_update": False, "style": {"description_width": "120px"}}
        self.controls = {
            "dt": w.FloatLogSlider(knobs.dt, base=10, min=-4.5, max=-1.5, description="dt (s)",
                                   readout_format=".1e", **slider),
            "elasticity": w.FloatSlider(knobs.elasticity, min=0, max=1, step=0.05, description="elasticity",
                                        **slider),
            "vdw_r0": w.FloatSlider(knobs.vdw_r0, min=0, max=30, step=0.5, description="vdW R0 (px)", **slider),
            "thermal": w.FloatSlider(knobs.thermal, min=0, max=5, step=0.1, description="thermal (x thesis)",
                                     **slider),
            "drag": w.FloatSlider(knobs.drag, min=0, max=2, step=0.025, description="drag f (1/s)", **slider),
            "gravity": w.ToggleButtons(options=GRAVITY_MODES, value=knobs.gravity, description="gravity",
                                       style={"button_width": "auto"}),
            "gravity_magnitude": w.FloatText(knobs.gravity_magnitude, description="g (px/s²)", **text),
            "engine": w.ToggleButtons(options=tuple(ENGINES), value=knobs.engine, description="engine",
                                      style={"button_width": "auto"}),
            "frame_steps": w.IntSlider(self.live.frame_steps, min=1, max=500, description="steps/frame", **slider),
            **{name: w.FloatText(value, description=name[5:], **text) for name, value in
               (("wall_x0", width / 2), ("wall_y0", 0.0), ("wall_x1", width / 2), ("wall_y1", height / 2))},
            "pitch": w.FloatText(round(GRATING_WIDTH, 2), description="pitch (px)", **text),
            "n_dots": w.IntText(20, description="N", **text),
            "mean_diameter": w.FloatText(15.0, description="diameter (px)", **text),
            "sigma": w.FloatText(0.0, description="sigma", **text),
            "interval": w.FloatText(1.0, description="interval (s)", **text),
            "state_path": w.Text("board.npz", description="checkpoint", **text),
            "movie_path": w.Text("board.mp4", description="movie", **text),
        }
        # plain words, and icons from the front end's own icon font: no glyph a browser's fonts may lack
        self.buttons = {name: w.Button(description=label, icon=icon, layout=w.Layout(width="auto"))
                        for name, label, icon in
                        (("start", "start", "play"), ("pause", "pause", "pause"), ("step", "step", "step-forward"),
                         ("add_wall", "add wall", ""), ("add_grating", "add grating", ""),
                         ("clear_walls", "clear walls", ""), ("drop", "drop N dots", ""),
                         ("save", "save board", ""))}
        self.buttons["record"] = w.Button(layout=w.Layout(width="auto"))
        self.readout, self.status = w.HTML(), w.HTML()
        self._connect()
        self.figure = widget_figure((size, size))
        ax = self.figure.add_subplot()
        ax.set_xlabel("x (px)")
        ax.set_ylabel("y (px)")
        self._board = BoardArtists(ax)
        self.ui = self._layout(w)
        self._buttons_for(running=False)
        self.refresh()  # the canvas itself is drawn when the front end shows it (labrig.widgets)

    # -- wiring ----------------------------------------------------------------------------------

    def _connect(self) -> None:
        c, b = self.controls, self.buttons
        for name in ("dt", "elasticity", "vdw_r0", "thermal", "drag", "gravity", "gravity_magnitude", "engine"):
            c[name].observe(lambda change, name=name: self._turn(name, change["new"]), "value")
        c["frame_steps"].observe(lambda change: setattr(self.live, "frame_steps", int(change["new"])), "value")
        b["start"].on_click(lambda _: self._act(self.start))
        b["pause"].on_click(lambda _: self.pause())
        b["step"].on_click(lambda _: self._act(self.live.advance))
        b["add_wall"].on_click(lambda _: self._act(
            self.live.add_wall, *(c[f"wall_{k}"].value for k in ("x0", "y0", "x1", "y1"))))
        b["add_grating"].on_click(lambda _: self._act(self.live.add_grating, c["pitch"].value))
        b["drop"].on_click(lambda _: self._act(self.live.drop, c["n_dots"].value, c["mean_diameter"].value,
                                                c["sigma"].value, c["interval"].value))
        b["clear_walls"].on_click(lambda _: self._act(self.live.clear_walls))
        b["save"].on_click(lambda _: self._act(self._save))
        b["record"].on_click(lambda _: self._act(self._record))

    def _layout(self, w):
        c, b = self.controls, self.buttons
        knobs = w.VBox([c[k] for k in ("engine", "dt", "elasticity", "vdw_r0", "thermal", "drag", "gravity",
                                        "gravity_magnitude", "frame_steps")])
        build = w.VBox([  # two fields a row at most: the tab fits the 340 px column
            w.HBox([c["wall_x0"], c["wall_y0"]]), w.HBox([c["wall_x1"], c["wall_y1"]]),
            w.HBox([b["add_wall"], b["clear_walls"]]), w.HBox([c["pitch"], b["add_grating"]]),
            w.HBox([c["n_dots"], c["mean_diameter"]]), w.HBox([c["sigma"], c["interval"]]), b["drop"],
            w.HBox([c["state_path"], b["save"]]), w.HBox([c["movie_path"], b["record"]]),
        ])
        tabs = w.Tab([knobs, build])
        tabs.set_title(0, "parameters")
        tabs.set_title(1, "walls, dots, files")
        run = w.HBox([b["start"], b["pause"], b["step"]])
        side = w.VBox([run, tabs, self.readout, self.status], layout=w.Layout(width="340px"))
        return w.HBox([self.figure.canvas, side], layout=w.Layout(flex_flow="row wrap"))  # narrow: controls below

    def _turn(self, name: str, value) -> None:
        """Set knob ``name``; a refused value is reported and the control shows the knob again."""
        if self._restoring:
            return
        self._act(self.live.set, **{name: value})
        if getattr(self.live.knobs, name) != value:
            self._restoring = True
            try:
                self.controls[name].value = getattr(self.live.knobs, name)
            finally:
                self._restoring = False

    def _act(self, action, *args, **kwargs) -> None:
        """Do what a control asks, then redraw; a returned message or an error goes to the status line."""
        try:
            message = action(*args, **kwargs)
        except (ValueError, OSError, RuntimeError) as exc:
            self.status.value = _error(f"{type(exc).__name__}: {exc}")
        else:
            self.status.value = html.escape(message) if isinstance(message, str) else ""
        self.refresh()

    def _save(self) -> str:
        return f"saved {self.live.save(self.controls['state_path'].value)}"

    def _record(self) -> str:
        """Start recording, or finish the movie being recorded."""
        if self.live.recording:
            return f"wrote {self.live.stop_recording()}"
        self.live.record(self.controls["movie_path"].value)
        return f"recording to {self.controls['movie_path'].value}"

    # -- running ---------------------------------------------------------------------------------

    @property
    def sim(self):
        """The `qdots.Simulation` now running (a new one after each knob change)."""
        return self.live.sim

    @property
    def running(self) -> bool:
        """True while the live task is advancing the board."""
        return self._task is not None and not self._task.done()

    def step(self) -> None:
        """Advance one frame (``frame_steps`` time steps) and redraw."""
        self.live.advance()
        self.refresh()

    def start(self) -> None:
        """Run frames in the background on the running asyncio loop (the kernel's) until `pause`.

        Raises
        ------
        RuntimeError
            Outside a running event loop (not in a notebook): use `step`.
        """
        if self.running:
            return
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            raise RuntimeError("start() needs a running asyncio event loop, as in a Jupyter kernel; "
                               "outside one, call step()") from None
        self._task = loop.create_task(self._run())
        self._buttons_for(running=True)

    def pause(self) -> None:
        """Stop after the current frame."""
        if self._task is not None:
            self._task.cancel()
            self._task = None
        self._buttons_for(running=False)

    async def _run(self) -> None:
        try:
            while True:
                try:
                    self.live.advance()
                except ValueError as exc:  # a full board: say so, the run goes on
                    self.status.value = _error(str(exc))
                self.refresh()
                await asyncio.sleep(self.frame_pause)
        except asyncio.CancelledError:
            raise
        except Exception as exc:  # a task's error is otherwise lost: show it and stop
            self.status.value = _error(f"stopped: {type(exc).__name__}: {exc}")
            self._buttons_for(running=False)

    def _buttons_for(self, running: bool) -> None:
        self.buttons["start"].disabled = running
        self.buttons["pause"].disabled = not running
        self.buttons["step"].disabled = running

    def refresh(self) -> None:
        """Redraw the board and the readout."""
        self._board.draw(self.live.sim.state())
        r = self.live.readout()
        self.readout.value = _html_table([
            ("time", f"{r['time_s']:.2f} s"), ("dots", f"{r['n_dots']} (+{r['pending']} queued)"),
            ("interior proportion", f"{r['interior_fraction']:.3f}"),
            ("mean neighbours", f"{r['mean_neighbours']:.2f}"),
            ("ψ6 global / local", f"{r['psi6_global']:.3f} / {r['psi6_local']:.3f}"),
            ("worst overlap", f"{100 * r['max_overlap']:.2f} % of a radius"),
            ("speed", f"{r['speed']:.2g} x real time"),
        ])
        recording = self.live.recording
        self.buttons["record"].description = "stop recording" if recording else "record MP4"
        self.buttons["record"].icon = "stop" if recording else "circle"
        self.figure.canvas.draw_idle()

    def close(self) -> None:
        """Stop the task, finish a movie being recorded, close the widgets."""
        self.pause()
        self.live.stop_recording()
        self.ui.close()

    def _repr_mimebundle_(self, **kwargs):
        return self.ui._repr_mimebundle_(**kwargs)
